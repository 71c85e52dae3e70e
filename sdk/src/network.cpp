// libphalanx on the lab network (phalanx/network.hpp, docs/sdk.md §"Devices on the network"): the devices that
// phalanxd's DDS bridges announce, and a commander of one of them by its name over rt/<name>/command.
#include "phalanx/network.hpp"

#include <arpa/inet.h>

#include <cstdio>
#include <ctime>

#include <dds/dds.h>

#include "phalanx/dds_namespace.h"
#include "phalanx/protocol/devices.h"
#include "ros2_msgs.h"

namespace phalanx {
namespace {

constexpr const char* kDevicesTopic = "rt/phalanx/devices";  // one topic for every daemon (docs/dds.md)

int64_t clockNs(clockid_t id) {
  timespec ts{};
  clock_gettime(id, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}
int64_t wallNs() { return clockNs(CLOCK_REALTIME); }  // stamps (the daemons' are wall-clock)
int64_t monoNs() { return clockNs(CLOCK_MONOTONIC); }  // waits

/// A domain restricted to one interface when one is named (else Cyclone's default choice), and a participant in
/// it. Deleting `root` deletes everything created under it.
struct Participant {
  dds_entity_t root = 0, participant = 0;

  explicit Participant(const NetworkOptions& o) {
    if (o.domain > 232) throw Error(PHALANX_EARG, "network: domain " + std::to_string(o.domain) + " is beyond 232");
    if (!o.interface.empty()) {
      in_addr a{};
      const bool address = inet_pton(AF_INET, o.interface.c_str(), &a) == 1;
      const std::string xml = "<CycloneDDS><Domain Id=\"any\"><General><Interfaces><NetworkInterface " +
                              std::string(address ? "address" : "name") + "=\"" + o.interface +
                              "\"/></Interfaces></General></Domain></CycloneDDS>";
      root = dds_create_domain(o.domain, xml.c_str());
      if (root < 0) {
        throw Error(PHALANX_ECONNECT, "network: cannot use interface '" + o.interface + "' on domain " +
                                          std::to_string(o.domain) + ": " + dds_strretcode(root));
      }
    }
    participant = dds_create_participant(o.domain, nullptr, nullptr);
    if (participant < 0) {
      if (root > 0) dds_delete(root);
      throw Error(PHALANX_ECONNECT, std::string("network: cannot join the DDS domain: ") + dds_strretcode(participant));
    }
    if (root <= 0) root = participant;
  }
  ~Participant() { dds_delete(root); }
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  /// A reader or writer of `name`, XCDR1 as every Phalanx topic; throws naming the topic.
  dds_entity_t open(const dds_topic_descriptor_t* desc, const std::string& name, dds_qos_t* q, bool reader) const {
    const dds_data_representation_id_t rep[] = {DDS_DATA_REPRESENTATION_XCDR1};
    dds_qset_data_representation(q, 1, rep);
    const dds_entity_t t = dds_create_topic(participant, desc, name.c_str(), q, nullptr);
    const dds_entity_t e = t < 0 ? t : reader ? dds_create_reader(participant, t, q, nullptr)
                                              : dds_create_writer(participant, t, q, nullptr);
    dds_delete_qos(q);
    if (e < 0) throw Error(PHALANX_ECONNECT, "network: cannot open " + name + ": " + dds_strretcode(e));
    return e;
  }
};

dds_qos_t* qos(dds_reliability_kind_t r, dds_durability_kind_t d, dds_history_kind_t h, int32_t depth) {
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, r, DDS_MSECS(100));
  dds_qset_durability(q, d);
  dds_qset_history(q, h, depth);
  return q;
}

/// The announcements heard within discovery_s, the newest per host and name.
std::vector<NetworkDevice> listen(const Participant& p, double seconds) {
  const dds_entity_t r = p.open(&phalanx_msgs_msg_dds__DeviceAnnouncement__desc, kDevicesTopic,
                                qos(DDS_RELIABILITY_RELIABLE, DDS_DURABILITY_TRANSIENT_LOCAL, DDS_HISTORY_KEEP_ALL, 0),
                                true);
  std::vector<NetworkDevice> out;
  std::vector<int64_t> stamp;  // of out[i]'s announcement
  const int64_t end = monoNs() + static_cast<int64_t>(seconds * 1e9);
  constexpr int kBatch = 32;
  void* samples[kBatch] = {};
  dds_sample_info_t infos[kBatch];
  while (monoNs() < end) {
    const dds_return_t n = dds_take(r, samples, infos, kBatch, kBatch);
    for (dds_return_t i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const auto& m = *static_cast<const phalanx_msgs_msg_dds__DeviceAnnouncement_*>(samples[i]);
      const int64_t st = static_cast<int64_t>(m.stamp.sec) * 1000000000 + m.stamp.nanosec;
      NetworkDevice d{m.host, m.name, m.device_type, m.device_spec, m.state, m.rate_hz, m.firmware_build_id, m.commands, 0.0};
      size_t k = 0;
      while (k < out.size() && !(out[k].host == d.host && out[k].name == d.name)) ++k;
      if (k == out.size()) {
        out.push_back(d);
        stamp.push_back(st);
      } else if (st >= stamp[k]) {
        out[k] = d;
        stamp[k] = st;
      }
    }
    if (n > 0) dds_return_loan(r, samples, n);
    else dds_sleepfor(DDS_MSECS(20));
  }
  const int64_t now = wallNs();
  for (size_t k = 0; k < out.size(); ++k) out[k].age_s = 1e-9 * static_cast<double>(now - stamp[k]);
  return out;
}

std::string seconds(double s) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f s", s);
  return b;
}

/// Values a command of `kind` carries to a device of `type`; 0: not this device's kind.
size_t valueCount(CommandKind kind, const std::string& type) {
  for (const protocol::DeviceLayout* l : {&protocol::kGlove5Layout, &protocol::kSeaFingerLayout, &protocol::kPantographLayout}) {
    if (type != l->name) continue;
    switch (kind) {
      case CommandKind::kRaw: return l->setpoint_count;
      case CommandKind::kGloveFingertipForce: return l->type == protocol::DeviceType::kGlove5 ? 10 : 0;
      case CommandKind::kSeaFingerTorque: return l->type == protocol::DeviceType::kSeaFinger ? 2 : 0;
      case CommandKind::kPenWrench: return l->type == protocol::DeviceType::kPantograph ? 6 : 0;
    }
  }
  return 0;
}

}  // namespace

std::vector<NetworkDevice> listNetworkDevices(const NetworkOptions& options) {
  if (!(options.discovery_s > 0.0 && options.discovery_s <= 60.0)) {
    throw Error(PHALANX_EARG, "network: discovery_s must be in (0, 60] s");
  }
  Participant p(options);
  return listen(p, options.discovery_s);
}

struct RemoteDevice::Impl {
  explicit Impl(const NetworkOptions& o) : p(o) {}
  Participant p;
  NetworkDevice device;
  dds_entity_t command_w = 0, joints_r = 0, joints_ws = 0;
  bool released = false;
  std::string error;
};

RemoteDevice::RemoteDevice(const std::string& name, const NetworkOptions& o) {
  if (!validDdsNamespace(name)) {
    throw Error(PHALANX_EARG, "network: '" + name + "' is not a device name (letters, digits, _ and / between parts, not starting with a digit)");
  }
  if (!(o.discovery_s > 0.0 && o.discovery_s <= 60.0)) throw Error(PHALANX_EARG, "network: discovery_s must be in (0, 60] s");
  auto impl = std::make_unique<Impl>(o);
  std::vector<NetworkDevice> found;
  std::string hosts;
  for (const NetworkDevice& d : listen(impl->p, o.discovery_s)) {
    if (d.name != name || (!o.host.empty() && d.host != o.host)) continue;
    found.push_back(d);
    hosts += (hosts.empty() ? "" : ", ") + d.host;
  }
  const std::string where = " on domain " + std::to_string(o.domain) + (o.host.empty() ? "" : " from host " + o.host);
  if (found.empty()) {
    throw Error(PHALANX_ECONNECT, "network: no daemon announced a device '" + name + "'" + where + " within " +
                                      seconds(o.discovery_s) + " (phalanx devices lists them)");
  }
  if (found.size() > 1) throw Error(PHALANX_EREFUSED, "network: '" + name + "' is announced by several hosts (" + hosts + "): name one");
  const NetworkDevice& d = found.front();
  if (d.state == "stopped") throw Error(PHALANX_EREFUSED, "network: '" + name + "' on " + d.host + " has stopped");
  if (!d.commands) {
    throw Error(PHALANX_EREFUSED, "network: '" + name + "' on " + d.host +
                                      " does not take commands over the network (its daemon's dds.commands.enabled is off)");
  }
  impl->device = d;
  // The daemon's command reader is reliable (docs/dds.md §"QoS"); keep-last: a newer command replaces an older
  // one not yet delivered, as the daemon keeps only the newest.
  impl->command_w = impl->p.open(&phalanx_msgs_msg_dds__Command__desc, "rt/" + name + "/command",
                                 qos(DDS_RELIABILITY_RELIABLE, DDS_DURABILITY_VOLATILE, DDS_HISTORY_KEEP_LAST, 8), false);
  // A volatile reliable writer delivers only to readers it has matched, and the reader drops what arrives before
  // it has matched the writer in turn (its own discovery, which the writer cannot observe): wait for the
  // writer's match, then a settle time for the reader's, before the first command. Without the settle time one
  // command in about two sessions was lost (one host: 99 of 100 received in 2 of 4 runs of remote_press); with
  // it, none in 6 runs.
  dds_publication_matched_status_t st{};
  const int64_t until = monoNs() + static_cast<int64_t>(o.discovery_s * 1e9);
  while (dds_get_publication_matched_status(impl->command_w, &st) == DDS_RETCODE_OK && st.current_count == 0 &&
         monoNs() < until) {
    dds_sleepfor(DDS_MSECS(10));
  }
  if (st.current_count == 0) {
    throw Error(PHALANX_ECONNECT, "network: the command reader of '" + name + "' on " + d.host + " did not match within " +
                                      seconds(o.discovery_s));
  }
  dds_sleepfor(DDS_MSECS(250));
  impl->joints_r = impl->p.open(&sensor_msgs_msg_dds__JointState__desc, "rt/" + name + "/joint_states",
                                qos(DDS_RELIABILITY_BEST_EFFORT, DDS_DURABILITY_VOLATILE, DDS_HISTORY_KEEP_LAST, 1), true);
  impl->joints_ws = dds_create_waitset(impl->p.participant);
  const dds_entity_t rc = dds_create_readcondition(impl->joints_r, DDS_ANY_STATE);
  if (impl->joints_ws < 0 || rc < 0 || dds_waitset_attach(impl->joints_ws, rc, 0) != DDS_RETCODE_OK) {
    throw Error(PHALANX_ECONNECT, "network: cannot wait on " + name + "/joint_states");
  }
  impl_ = std::move(impl);
}

RemoteDevice::~RemoteDevice() { release(); }

const NetworkDevice& RemoteDevice::device() const { return impl_->device; }
const std::string& RemoteDevice::lastError() const { return impl_->error; }
size_t RemoteDevice::setpointCount() const { return valueCount(CommandKind::kRaw, impl_->device.type); }

bool RemoteDevice::send(const Command& cmd) {
  Impl& s = *impl_;
  const size_t n = valueCount(cmd.kind, s.device.type);
  if (s.released) s.error = "released";
  else if (n == 0) s.error = "command kind " + std::to_string(static_cast<int>(cmd.kind)) + " is not a " + s.device.type + "'s";
  else if (cmd.mode != Mode::kSetpoint && cmd.mode != Mode::kTransparent) s.error = "mode must be setpoint or transparent";
  else s.error.clear();
  if (!s.error.empty()) return false;
  const float* v = cmd.kind == CommandKind::kRaw ? cmd.setpoint.data() : cmd.model.data();
  phalanx_msgs_msg_dds__Command_ m{};
  const int64_t now = wallNs();
  m.header.stamp.sec = static_cast<int32_t>(now / 1000000000);
  m.header.stamp.nanosec = static_cast<uint32_t>(now % 1000000000);
  m.header.frame_id = const_cast<char*>("");
  m.mode = static_cast<uint8_t>(cmd.mode);
  m.kind = static_cast<uint8_t>(cmd.kind);
  m.values._length = m.values._maximum = static_cast<uint32_t>(n);
  m.values._buffer = const_cast<float*>(v);  // Cyclone only reads a sample it writes
  m.values._release = false;
  const dds_return_t rc = dds_write(s.command_w, &m);
  if (rc != DDS_RETCODE_OK) s.error = std::string("write: ") + dds_strretcode(rc);
  return rc == DDS_RETCODE_OK;
}

bool RemoteDevice::waitJoints(RemoteJoints& out, int timeout_ms) {
  Impl& s = *impl_;
  const int64_t end = monoNs() + static_cast<int64_t>(timeout_ms) * 1000000;
  for (;;) {
    void* sample = nullptr;
    dds_sample_info_t info;
    const dds_return_t n = dds_take(s.joints_r, &sample, &info, 1, 1);
    if (n > 0) {
      const auto& m = *static_cast<const sensor_msgs_msg_dds__JointState_*>(sample);
      if (info.valid_data) {
        out.name.assign(m.name._buffer, m.name._buffer + m.name._length);
        out.position.assign(m.position._buffer, m.position._buffer + m.position._length);
        out.velocity.assign(m.velocity._buffer, m.velocity._buffer + m.velocity._length);
        out.effort.assign(m.effort._buffer, m.effort._buffer + m.effort._length);
        out.stamp_ns = static_cast<int64_t>(m.header.stamp.sec) * 1000000000 + m.header.stamp.nanosec;
        ++out.received;
      }
      dds_return_loan(s.joints_r, &sample, n);
      if (info.valid_data) return true;
      continue;
    }
    const int64_t left = end - monoNs();
    if (left <= 0) return false;
    dds_waitset_wait(s.joints_ws, nullptr, 0, left);
  }
}

void RemoteDevice::release() {
  if (!impl_ || impl_->released) return;
  impl_->released = true;
  // A keyless topic has one instance: disposing it is the hand-back the daemon acts on (docs/dds.md §"Commands").
  phalanx_msgs_msg_dds__Command_ m{};
  m.header.frame_id = const_cast<char*>("");
  dds_dispose(impl_->command_w, &m);
  dds_wait_for_acks(impl_->command_w, DDS_SECS(1));  // reliable: the dispose reaches the daemon before we leave
}

}  // namespace phalanx
