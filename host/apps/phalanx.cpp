// phalanx: the user's command-line entry point. Each subcommand (or family) has its options' setup and its run
// function here or in its own file; main reads as the table of contents.
//   phalanx run            start a session (the simulated firmware too, for sim:* devices) and print a summary
//   phalanx version        protocol and build information
//   phalanx mcu-diag       an MCU board's control-tick statistics through the protocol
//   phalanx param          device parameters, persistent settings, YAML backup and restore (param_cli.cpp)
//   phalanx flash          check a firmware image and write it into a board (flash_cli.cpp)
//   phalanx update         firmware update over the board's own link (update_cli.cpp)
//   phalanx can            CAN bus-load budget and measurement
//   phalanx devices        the devices the daemons on the network announce over DDS
//   phalanx bench          single benches and bench plans (bench_cli.cpp)
//   phalanx sea-calibrate  SEA finger subject parameters from a recording (001 eq 12)
//   phalanx design         design tools (design_cli.cpp)
//   phalanx status|start|… the therapy API's client (therapy_cli.h)
#include <cstdio>
#include <iostream>

#include "bench_cli.h"
#include "cli_args.h"
#include "common_options.h"
#include "design_cli.h"
#include "flash_cli.h"
#include "param_cli.h"
#include "phalanx/host/can_budget.h"
#include "phalanx/host/config.h"
#include "phalanx/host/mcu_diag.h"
#include "phalanx/host/program_name.h"
#include "phalanx/host/sea/sea_calibrate.h"
#include "phalanx/protocol/messages.h"
#include "therapy_cli.h"
#include "update_cli.h"
#ifdef PHALANX_NETWORK
#include "phalanx/network.hpp"
#endif

namespace {

using namespace phalanx::host;

// ---- phalanx run ------------------------------------------------------------------------------------------------

struct RunCommand {
  CLI::App* app = nullptr;
  RunOptions opt;
  std::string config_path;
  bool no_rt = false;
  bool json = false;

  explicit RunCommand(CLI::App& parent) {
    app = parent.add_subcommand("run", "run a device session (default device: sim:glove5)");
    addRunOptions(*app, opt, config_path, no_rt, json);
  }

  /// The options given on the command line override the config file's: parse once more over the file's values.
  int applyConfigFile(CLI::App& top, int argc, char** argv) {
    if (config_path.empty()) return -1;
    RunOptions from_file;
    if (const std::string err = loadConfigFile(config_path, from_file); !err.empty()) {
      std::fprintf(stderr, "phalanx: error: %s\n", err.c_str());
      return cli::kExitBadArguments;
    }
    opt = from_file;
    if (int rc = 0; !cli::parseArgs(top, argc, argv, "phalanx", rc)) return rc;
    return -1;
  }

  int run(CLI::App& top, int argc, char** argv) {
    if (const int rc = applyConfigFile(top, argc, argv); rc >= 0) return rc;
    if (const std::string err = checkSessionLength(opt.seconds, opt.rate_hz); !err.empty()) {
      const std::string where = app->count("--seconds") > 0 ? "--seconds" : config_path + ": seconds";
      std::fprintf(stderr, "phalanx: error: %s: %s\n", where.c_str(), err.c_str());
      return cli::kExitBadArguments;
    }
    if (no_rt) opt.realtime = false;
    if (opt.seconds == 0.0 && json) opt.seconds = 10.0;
    installStopSignals();
    nlohmann::json summary;
    const int rc = runSession(opt, summary);
    printSummary(summary, json);
    return rc;
  }
};

// ---- phalanx version --------------------------------------------------------------------------------------------

int runVersion() {
  std::printf("phalanx %s, wire protocol v%u\n", PHALANX_PROJECT_VERSION, phalanx::protocol::kProtocolVersion);
  return 0;
}

// ---- phalanx mcu-diag -------------------------------------------------------------------------------------------

struct McuDiagCommand {
  CLI::App* app = nullptr;
  std::string device;
  double timeout_s = 2.0;

  explicit McuDiagCommand(CLI::App& parent) {
    app = parent.add_subcommand(
        "mcu-diag", "read an MCU board's control-tick statistics and firmware build through the protocol (JSON)");
    app->add_option("--device", device, "serial:<path> of the board (e.g. the QEMU board's pty)")->required();
    app->add_option("--timeout", timeout_s, "seconds to wait for each answer")->check(cli::inRange(0.1, 60.0));
  }

  int run() const {
    if (device.rfind("serial:", 0) != 0) {
      std::fprintf(stderr, "phalanx: error: --device must be serial:<path> (got '%s')\n", device.c_str());
      return cli::kExitBadArguments;
    }
    std::string error;
    const nlohmann::json result = readMcuDiagnostics(device.substr(7), timeout_s, error);
    if (!error.empty()) {
      std::fprintf(stderr, "phalanx: error: %s\n", error.c_str());
      return 4;
    }
    std::cout << result.dump(2) << std::endl;
    return 0;
  }
};

// ---- phalanx devices --------------------------------------------------------------------------------------------

/// Every device announced on rt/phalanx/devices within the listening time (docs/dds.md "Devices on the network").
struct DevicesCommand {
  CLI::App* app = nullptr;
  uint32_t domain = 0;
  std::string interface;
  double seconds = 2.0;
  bool json = false;

  explicit DevicesCommand(CLI::App& parent) {
    app = parent.add_subcommand("devices", "list the devices announced over DDS (rt/phalanx/devices)");
    app->add_option("--domain", domain, "DDS domain id (dds.domain_id)")->check(cli::inRange<uint32_t>(0, 232));
    app->add_option("--interface", interface, "network interface name or IPv4 address (dds.interface)");
    app->add_option("--seconds", seconds, "listen this long")->check(cli::inRange(0.1, 60.0));
    app->add_flag("--json", json, "one JSON array");
  }

  int run() const {
#ifdef PHALANX_NETWORK
    std::vector<::phalanx::NetworkDevice> seen;
    try {
      ::phalanx::NetworkOptions o;
      o.domain = domain;
      o.interface = interface;
      o.discovery_s = seconds;
      seen = ::phalanx::listNetworkDevices(o);  // libphalanx's network part (docs/sdk.md)
    } catch (const ::phalanx::Error& e) {
      std::fprintf(stderr, "phalanx devices: %s\n", e.what());
      return 3;
    }
    if (json) {
      nlohmann::json a = nlohmann::json::array();
      for (const auto& d : seen) {
        a.push_back({{"host", d.host}, {"name", d.name}, {"type", d.type}, {"device", d.spec}, {"state", d.state},
                     {"rate_hz", d.rate_hz}, {"firmware_build_id", d.firmware_build_id}, {"commands", d.commands},
                     {"age_s", d.age_s}});
      }
      std::printf("%s\n", a.dump(2).c_str());
      return 0;
    }
    std::printf("%-16s %-24s %-11s %-8s %-9s %s\n", "HOST", "NAME", "TYPE", "RATE_HZ", "COMMANDS", "STATE");
    for (const auto& d : seen) {
      std::printf("%-16s %-24s %-11s %-8.0f %-9s %s\n", d.host.c_str(), d.name.c_str(), d.type.c_str(), d.rate_hz,
                  d.commands ? "on" : "off", d.state.c_str());
    }
    if (seen.empty()) std::fprintf(stderr, "phalanx devices: none announced on domain %u within %.1f s\n", domain, seconds);
    return 0;
#else
    std::fprintf(stderr, "phalanx devices: this phalanx was built without Cyclone DDS (install cyclonedds-dev and "
                         "rebuild; docs/dds.md)\n");
    return 3;
#endif
  }
};

// ---- phalanx can ------------------------------------------------------------------------------------------------

struct CanCommands {
  CLI::App* app = nullptr;
  CLI::App* budget = nullptr;
  double rate_hz = 1000, bps = 1e6, data_bps = 5e6;
  std::string log;

  explicit CanCommands(CLI::App& parent) {
    app = parent.add_subcommand("can", "CAN bus-load budget (computed) and measurement (from candump -L)");
    app->require_subcommand(1);
    budget = app->add_subcommand("budget", "bus load of every device per tick, from the CAN mapping");
    budget->add_option("--rate-hz", rate_hz, "ticks per second")->check(cli::inRange(1.0, 10000.0));
    budget->add_option("--bitrate", bps, "nominal bit rate")->check(cli::inRange(1e4, 1e6));
    CLI::App* load = app->add_subcommand("load", "bus load measured from a candump -L log");
    load->add_option("--log", log, "candump -L log file")->required();
    load->add_option("--bitrate", bps, "nominal bit rate")->check(cli::inRange(1e4, 1e6));
    load->add_option("--data-bitrate", data_bps, "CAN-FD data-phase bit rate")->check(cli::inRange(1e4, 1.2e7));
  }

  int run() const {
    const nlohmann::json r = budget->parsed() ? canBudget(rate_hz, bps) : canLoadFromLog(log, bps, data_bps);
    std::cout << r.dump(2) << std::endl;
    return r.contains("error") ? 1 : 0;
  }
};

// ---- phalanx sea-calibrate --------------------------------------------------------------------------------------

struct SeaCalibrateCommand {
  CLI::App* app = nullptr;
  std::string csv, subject;
  int stride = 1, smooth = 1;
  bool json = false;

  explicit SeaCalibrateCommand(CLI::App& parent) {
    app = parent.add_subcommand("sea-calibrate", "estimate SEA finger subject parameters (001 eq 12)");
    app->add_option("--recording", csv,
                    "CSV over a full range of motion (phalanx run --record; recommended: 60 s at 1 kHz, --smooth 51 "
                    "--stride 10)")
        ->required();
    app->add_option("--subject", subject, "subject YAML to update (created if absent)")->required();
    app->add_option("--stride", stride, "use every n-th row")->check(cli::inRange(1, 1000));
    app->add_option("--smooth", smooth,
                    "centred quadratic Savitzky-Golay smoothing over n rows before the fit (1 kHz recording: 51)")
        ->check(cli::inRange(1, 1001));
    app->add_flag("--json", json, "JSON output");
  }

  int run() const { return phalanx::host::sea::seaCalibrateCommand(csv, subject, json, stride, smooth); }
};

}  // namespace

int main(int argc, char** argv) {
  setProgramName("phalanx");
  CLI::App app{"phalanx - Phalanx haptic control stack"};
  app.require_subcommand(1);
  app.option_defaults()->always_capture_default();  // help shows every default ("[1000]")

  RunCommand run(app);
  CLI::App* version = app.add_subcommand("version", "print version information");
  McuDiagCommand mcu_diag(app);
  ParamCommands param(app);
  FlashCommand flash_cmd(app);
  UpdateCommand update_cmd(app);
  CanCommands can(app);
  DevicesCommand devices(app);
  BenchCommands bench(app);
  SeaCalibrateCommand sea_cal(app);
  cli::TherapyCli therapy;
  cli::addTherapyCommands(app, therapy);
  DesignCommands design(app);
  cli::refuseEmptyValues(app);
  cli::hideUnsetDefaults(app);

  if (int rc = 0; !cli::parseArgs(app, argc, argv, "phalanx", rc)) return rc;
  if (design.parsed()) return design.run();
  if (bench.parsed()) return bench.run();
  if (sea_cal.app->parsed()) return sea_cal.run();
  if (can.app->parsed()) return can.run();
  if (devices.app->parsed()) return devices.run();
  if (const int rc = cli::runTherapyCommands(therapy); rc >= 0) return rc;
  if (mcu_diag.app->parsed()) return mcu_diag.run();
  if (param.parsed()) return param.run();
  if (flash_cmd.app->parsed()) return flash_cmd.run();
  if (update_cmd.app->parsed()) return update_cmd.run();
  if (version->parsed()) return runVersion();
  return run.run(app, argc, argv);
}
