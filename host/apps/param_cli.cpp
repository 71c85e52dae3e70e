// phalanx param: each subcommand is open device → handshake → its requests → close; nothing is written to the
// device before every input has been checked, and a restore that the device refuses half-way is rolled back.
#include "param_cli.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>

#include "cli_args.h"
#include "phalanx/host/device_link.h"
#include "phalanx/host/params.h"
#include "phalanx/linux/realtime.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::host {

namespace {

constexpr int kExitDifferent = 1;  // param diff: the device and the file differ
constexpr int kExitNoDevice = 3;   // cannot open, no answer
constexpr int kExitRefused = 4;    // the device refused a request

const char* statusName(protocol::ParamStatus s) {
  switch (s) {
    case protocol::ParamStatus::kOk: return "ok";
    case protocol::ParamStatus::kUnknownParam: return "unknown to this firmware";
    case protocol::ParamStatus::kOutOfRange: return "out of range";
    case protocol::ParamStatus::kReadOnly: return "read-only";
    case protocol::ParamStatus::kBusy: return "busy: the device's outputs are active, or a save or an update is under way";
    case protocol::ParamStatus::kFailed: return "failed on the device (flash write)";
  }
  return "unknown status";
}

/// An open device with a handshaken session.
struct Device {
  std::unique_ptr<DeviceLink> link;
  std::unique_ptr<HostSession> session;
  uint64_t timeout_ns = 0;
  protocol::DeviceType type = protocol::DeviceType::kAny;
  uint16_t layout_version = 0;  ///< the settings layout the firmware writes (0: it keeps no settings)
  std::vector<params::ParamInfo> table;

  /// One ParamGet (set = false) or ParamSet; "" and the answer, or why there is none.
  std::string request(bool set, uint16_t id, float v, protocol::ParamValue& answer) {
    if (set ? !session->sendParamSet(id, v) : !session->sendParamGet(id)) return "cannot send to " + link->where();
    link->push();
    const uint64_t t0 = linux_hal::monotonicNs();
    while (!(session->lastParamValid() && session->lastParam().param_id == id)) {
      if (linux_hal::monotonicNs() - t0 > timeout_ns) return "no answer from the device to parameter " + std::to_string(id);
      usleep(500);
      session->poll(linux_hal::monotonicNs());
    }
    answer = session->lastParam();
    return {};
  }
  /// The persisted parameters' values by name.
  std::string readPersisted(std::map<std::string, float>& out) {
    for (const params::ParamInfo& p : table) {
      if (!p.persisted) continue;
      protocol::ParamValue a;
      if (std::string err = request(false, p.id, 0.0f, a); !err.empty()) return err;
      if (a.status != protocol::ParamStatus::kOk) return p.name + ": " + statusName(a.status);
      out[p.name] = a.value;
    }
    return {};
  }
  std::string buildId() const {
    char b[16];
    std::snprintf(b, sizeof b, "%08x", static_cast<unsigned>(session->deviceInfo().firmware_build_id));
    return b;
  }
};

std::string openDevice(const RunOptions& opt, double timeout_s, Device& d) {
  std::string error;
  d.link = openDeviceLink(opt, error);
  if (!d.link) return error;
  d.session = std::make_unique<HostSession>(d.link->makeSession());
  d.timeout_ns = static_cast<uint64_t>(timeout_s * 1e9);
  if (std::string err = handshakeDevice(*d.link, *d.session, timeout_s); !err.empty()) return err;
  d.type = d.session->deviceInfo().device_type;
  // Which parameters this firmware keeps: its settings layout (an older firmware keeps fewer).
  protocol::ParamValue a;
  if (std::string err = d.request(false, protocol::core_param::kSettingsLayout, 0.0f, a); !err.empty()) return err;
  if (a.status == protocol::ParamStatus::kOk && a.value >= 1.0f && a.value <= 65535.0f) {
    d.layout_version = static_cast<uint16_t>(a.value);
  }
  d.table = params::known(d.type, d.layout_version);
  return {};
}

/// The value argument of `param set`: a finite number, nothing after it.
bool parseValue(const std::string& text, float& v) {
  char* end = nullptr;
  const double x = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != 0 || !std::isfinite(x) || std::fabs(x) > 3.4e38) return false;
  v = static_cast<float>(x);
  return true;
}

int fail(int rc, const std::string& what) {
  std::fprintf(stderr, "phalanx: error: %s\n", what.c_str());
  return rc;
}

constexpr const char* kNoStore = "this firmware keeps no settings (no settings store on this board; docs/params.md)";

int saveOnDevice(Device& d) {
  protocol::ParamValue a;
  if (std::string err = d.request(true, protocol::core_param::kSettingsSave, 1.0f, a); !err.empty()) {
    return fail(kExitNoDevice, err);
  }
  if (a.status == protocol::ParamStatus::kUnknownParam) return fail(kExitRefused, kNoStore);
  if (a.status != protocol::ParamStatus::kOk) return fail(kExitRefused, std::string("save: ") + statusName(a.status));
  std::printf("saved: settings record %.0f\n", static_cast<double>(a.value));
  return 0;
}

int runList(Device& d, const std::string& yaml) {
  params::Backup backup;
  backup.device_type = protocol::layoutFor(d.type)->name;
  backup.build_id = d.buildId();
  std::printf("%-28s %-7s %-9s %s\n", "NAME", "ID", "ACCESS", "VALUE");
  for (const params::ParamInfo& p : d.table) {
    protocol::ParamValue a;
    if (std::string err = d.request(false, p.id, 0.0f, a); !err.empty()) return fail(kExitNoDevice, err);
    const char* access = p.access == params::Access::kReadOnly ? "ro" : p.access == params::Access::kAction ? "action" : "rw";
    const std::string acc = std::string(access) + (p.persisted ? ",saved" : "");
    if (a.status == protocol::ParamStatus::kOk) {
      std::printf("%-28s 0x%04x  %-9s %.9g\n", p.name.c_str(), p.id, acc.c_str(), static_cast<double>(a.value));
      if (p.persisted) backup.values[p.name] = a.value;
    } else {
      std::printf("%-28s 0x%04x  %-9s - (%s)\n", p.name.c_str(), p.id, acc.c_str(), statusName(a.status));
    }
  }
  if (yaml.empty()) return 0;
  std::ofstream f(yaml);
  f << params::toYaml(backup);
  if (!f.good()) return fail(cli::kExitBadArguments, "cannot write " + yaml);
  std::fprintf(stderr, "phalanx: backup of %zu settings written to %s\n", backup.values.size(), yaml.c_str());
  return 0;
}

}  // namespace

ParamCommands::ParamCommands(CLI::App& parent) {
  opt.device.clear();  // no default device: a parameter write must name its device
  app = parent.add_subcommand("param", "device parameters: list, get, set, save to the device's flash, YAML backup "
                                       "and restore (docs/params.md)");
  app->require_subcommand(1);
  auto common = [this](CLI::App* c) {
    c->add_option("--device", opt.device,
                  "sim:glove5 | sim:sea_finger | sim:pantograph | serial:PATH[@baud] | can:IF[:node][@flavor] | "
                  "usb:VID:PID[:serial]")
        ->required();
    c->add_option("--timeout", timeout_s, "seconds to wait for the handshake and each answer")->check(cli::inRange(0.1, 60.0));
    c->add_option("--firmware-sim", opt.firmware_sim, "sim: devices: path of the firmware-sim executable");
    c->add_option("--sim-settings", opt.sim_settings,
                  "sim: devices: the simulated board's settings flash file (kept between runs: a power cycle)");
    c->add_option("--sim-settings-layout", opt.sim_settings_layout,
                  "sim: devices: play the firmware that writes this settings layout version (0: the newest)")
        ->check(cli::inRange(0u, 255u));
  };
  list = app->add_subcommand("list", "every parameter the device answers, with its value");
  list->add_option("--yaml", yaml, "also write a backup of the saved settings to this YAML file");
  get = app->add_subcommand("get", "one parameter's value");
  get->add_option("name", key, "parameter name or id (0x0100)")->required();
  set = app->add_subcommand("set", "set one parameter (in the device's RAM; --save or param save keeps it)");
  set->add_option("name", key, "parameter name or id (0x0100)")->required();
  set->add_option("value", value, "the new value (a finite number)")->required();
  set->add_flag("--save", save_after_set, "then save the device's settings to its flash");
  save = app->add_subcommand("save", "save the device's settings to its flash (outputs must be off)");
  load = app->add_subcommand("load", "restore the settings from a backup (param list --yaml) and save them");
  load->add_option("file", file, "backup YAML")->required()->check(CLI::ExistingFile);
  diff = app->add_subcommand("diff", "the settings that differ between the device and a backup (exit 1 if any)");
  diff->add_option("file", file, "backup YAML")->required()->check(CLI::ExistingFile);
  for (CLI::App* c : {list, get, set, save, load, diff}) common(c);
}

int ParamCommands::run() {
  if (const std::string err = validate(opt); !err.empty()) return fail(cli::kExitBadArguments, err);
  float v = 0.0f;
  if (set->parsed() && !parseValue(value, v)) {
    return fail(cli::kExitBadArguments, "value '" + value + "' is not a finite number");
  }
  Device d;
  if (const std::string err = openDevice(opt, timeout_s, d); !err.empty()) return fail(kExitNoDevice, err);
  const int rc = [&]() -> int {
    if ((load->parsed() || (set->parsed() && save_after_set)) && d.layout_version == 0) {
      return fail(kExitRefused, kNoStore);  // refused before anything is set that could not be saved
    }
    if (list->parsed()) return runList(d, yaml);
    if (save->parsed()) return saveOnDevice(d);
    if (get->parsed() || set->parsed()) {
      std::string err;
      const params::ParamInfo* p = params::lookup(d.table, key, err);
      if (p == nullptr) return fail(cli::kExitBadArguments, err);
      if (set->parsed() && p->access == params::Access::kReadOnly) {
        return fail(cli::kExitBadArguments, p->name + " is read-only" +
                                                (p->id == protocol::core_param::kSettingsSave ? " (phalanx param save saves)" : ""));
      }
      if (set->parsed() && save_after_set && !p->persisted) {
        return fail(cli::kExitBadArguments, p->name + " is not a setting this firmware keeps (settings layout " +
                                                std::to_string(d.layout_version) + "): --save would not keep it");
      }
      protocol::ParamValue a;
      if (std::string e = d.request(set->parsed(), p->id, v, a); !e.empty()) return fail(kExitNoDevice, e);
      if (a.status != protocol::ParamStatus::kOk) return fail(kExitRefused, p->name + ": " + statusName(a.status));
      std::printf("%s = %.9g\n", p->name.c_str(), static_cast<double>(a.value));
      return set->parsed() && save_after_set ? saveOnDevice(d) : 0;
    }
    params::Backup backup;
    if (std::string err = params::readBackup(file, d.type, backup, d.layout_version); !err.empty()) {
      return fail(cli::kExitBadArguments, err);
    }
    std::map<std::string, float> now;
    if (std::string err = d.readPersisted(now); !err.empty()) return fail(kExitNoDevice, err);
    if (diff->parsed()) {
      const auto diffs = params::diff(now, backup.values);
      for (const params::Difference& x : diffs) {
        if (!x.in_file) std::printf("%s: device %.9g, not in %s\n", x.name.c_str(), static_cast<double>(x.device_value), file.c_str());
        else if (!x.on_device) std::printf("%s: not on the device, file %.9g\n", x.name.c_str(), static_cast<double>(x.file_value));
        else std::printf("%s: device %.9g, file %.9g\n", x.name.c_str(), static_cast<double>(x.device_value), static_cast<double>(x.file_value));
      }
      return diffs.empty() ? 0 : kExitDifferent;
    }
    // load: in the table's order (a mode before its gains); on a refusal, what was set goes back as it was.
    std::vector<const params::ParamInfo*> done;
    for (const params::ParamInfo& p : d.table) {
      const auto it = backup.values.find(p.name);
      if (it == backup.values.end()) continue;
      protocol::ParamValue a;
      std::string err = d.request(true, p.id, it->second, a);
      if (err.empty() && a.status != protocol::ParamStatus::kOk) err = p.name + " = " + std::to_string(it->second) + ": " + statusName(a.status);
      if (!err.empty()) {
        for (auto r = done.rbegin(); r != done.rend(); ++r) d.request(true, (*r)->id, now[(*r)->name], a);
        return fail(kExitRefused, file + ": " + err + "; nothing saved, the values set before it were put back");
      }
      done.push_back(&p);
    }
    std::printf("restored %zu settings from %s\n", done.size(), file.c_str());
    return saveOnDevice(d);
  }();
  d.link->close();
  return rc;
}

}  // namespace phalanx::host
