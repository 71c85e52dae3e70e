// The DDS bridge over Cyclone DDS's C API (Debian cyclonedds-dev 0.10.2). The message types are compiled from
// host/dds/idl/ros2_msgs.idl by idlc (CMake). Everything here runs on the bridge's own thread, never the loop's.
#include <arpa/inet.h>
#include <unistd.h>
#include <pthread.h>
#include <sched.h>
#include <dds/dds.h>

#include <atomic>
#include <cmath>
#include <ctime>
#include <thread>
#include <vector>

#include "phalanx/host/dds/dds_bridge.h"
#include "phalanx/host/client/client_port.h"
#include "phalanx/host/client/device_model.h"
#include "phalanx/host/dds/model_view.h"
#include "phalanx/host/stats.h"
#include "cyclone_domain.h"
#include "ros2_msgs.h"

namespace phalanx::host::dds {

std::string createDomain(uint32_t domain_id, const std::string& interface, dds_entity_t& domain) {
  if (interface.empty()) return {};
  in_addr a{};
  const bool address = inet_pton(AF_INET, interface.c_str(), &a) == 1;
  const std::string xml = "<CycloneDDS><Domain Id=\"any\"><General><Interfaces><NetworkInterface " +
                          std::string(address ? "address" : "name") + "=\"" + interface +
                          "\"/></Interfaces></General></Domain></CycloneDDS>";
  domain = dds_create_domain(domain_id, xml.c_str());
  if (domain < 0) {
    return "dds: cannot create domain " + std::to_string(domain_id) + " on interface '" + interface +
           "': " + dds_strretcode(domain);
  }
  return {};
}

namespace {

uint64_t clockNs(clockid_t id) {
  timespec ts{};
  clock_gettime(id, &ts);
  return static_cast<uint64_t>(ts.tv_sec) * 1000000000ull + static_cast<uint64_t>(ts.tv_nsec);
}

char* text(const std::string& s) { return const_cast<char*>(s.c_str()); }  // Cyclone only reads samples we write

nlohmann::json histogram(const Histogram& h) {
  return {{"count", h.count()}, {"p50_us", h.percentile(0.5)}, {"p99_us", h.percentile(0.99)}, {"max_us", h.max()}};
}

constexpr const char* kDevicesTopic = "rt/phalanx/devices";  // one topic for every daemon (docs/dds.md)

/// Reliable, transient-local (a late reader gets each writer's latest), XCDR1.
dds_qos_t* announceQos(bool reader) {
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
  if (reader) dds_qset_history(q, DDS_HISTORY_KEEP_ALL, 0);
  else dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  const dds_data_representation_id_t rep[] = {DDS_DATA_REPRESENTATION_XCDR1};
  dds_qset_data_representation(q, 1, rep);
  return q;
}

class CycloneBridge final : public Bridge {
 public:
  CycloneBridge(const DdsOptions& o, const BridgeDevice& dev, LoopPort& port)
      : opt_(o), dev_(dev), port_(port), stage_(std::make_unique<client::DeviceModelStage>(*dev.layout, dev_.geometry)),
        names_(modelNames(dev.layout->type)), ns_(topicNamespace(o, *dev.layout)) {
    for (const char c : ns_) frame_prefix_ += c == '/' ? '_' : c;
    frame_prefix_ += '_';
  }
  ~CycloneBridge() override { stop(); }

  std::string start() {
    if (std::string err = createDomain(opt_.domain_id, opt_.interface, domain_); !err.empty()) return err;
    participant_ = dds_create_participant(opt_.domain_id, nullptr, nullptr);
    if (participant_ < 0) return std::string("dds: cannot create the participant: ") + dds_strretcode(participant_);
    if (std::string err = createWriters(); !err.empty()) return err;
    offset_ns_ = static_cast<int64_t>(clockNs(CLOCK_REALTIME)) - static_cast<int64_t>(clockNs(CLOCK_MONOTONIC));
    running_ = true;
    thread_ = std::thread([this] { serve(); });
    if (cmd_r_ > 0) cmd_thread_ = std::thread([this] { serveCommands(); });
    return {};
  }

  void stop() override {
    if (running_.exchange(false)) {
      thread_.join();
      if (cmd_thread_.joinable()) cmd_thread_.join();
      announce("stopped");
    }
    if (domain_ > 0) {
      dds_delete(domain_);
    } else if (participant_ > 0) {
      dds_delete(participant_);
    }
    domain_ = participant_ = 0;
  }

  nlohmann::json summaryJson() const override {
    return {{"namespace", ns_},
            {"domain_id", opt_.domain_id},
            {"state_every_cycles", port_.stateDecimation()},
            {"offered", port_.offered()},
            {"dropped_full", port_.droppedFull()},
            {"state_samples", state_samples_},
            {"diagnostics_samples", diag_samples_},
            {"write_errors", write_errors_},
            {"telemetry_to_written", histogram(to_written_us_)},
            {"announcements", announcements_},
            {"commands", commandsJson()}};
  }

 private:
  dds_qos_t* makeQos(bool reliable, uint32_t depth) {
    dds_qos_t* q = dds_create_qos();
    dds_qset_reliability(q, reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT, DDS_MSECS(100));
    dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, static_cast<int32_t>(depth));
    // XCDR1, as ROS 2 uses (docs/dds.md): the types are @final, so this is also Cyclone's own choice.
    const dds_data_representation_id_t rep[] = {DDS_DATA_REPRESENTATION_XCDR1};
    dds_qset_data_representation(q, 1, rep);
    return q;
  }

  std::string writer(const dds_topic_descriptor_t* desc, const std::string& name, const dds_qos_t* q, dds_entity_t& w) {
    const dds_entity_t t = dds_create_topic(participant_, desc, name.c_str(), q, nullptr);
    if (t < 0) return "dds: cannot create topic " + name + ": " + dds_strretcode(t);
    w = dds_create_writer(participant_, t, q, nullptr);
    if (w < 0) return "dds: cannot create the writer of " + name + ": " + dds_strretcode(w);
    return {};
  }

  std::string createWriters() {
    dds_qos_t* state = makeQos(opt_.state_reliability == "reliable", opt_.state_depth);
    dds_qos_t* diag = makeQos(true, opt_.diagnostics_depth);
    std::string err;
    const std::string base = "rt/" + ns_ + "/";
    if (opt_.joint_states) err = writer(&sensor_msgs_msg_dds__JointState__desc, base + "joint_states", state, joints_w_);
    for (uint8_t b = 0; err.empty() && b < names_.body_count; ++b) {
      const std::string body = base + names_.bodies[b] + "/";
      if (opt_.poses) err = writer(&geometry_msgs_msg_dds__PoseStamped__desc, body + "pose", state, pose_w_[b]);
      if (err.empty() && opt_.wrenches) {
        err = writer(&geometry_msgs_msg_dds__WrenchStamped__desc, body + "wrench", state, wrench_w_[b]);
      }
      pose_frame_[b] = frame_prefix_ + names_.pose_frames[b];
      wrench_frame_[b] = frame_prefix_ + names_.wrench_frames[b];
    }
    if (err.empty() && opt_.diagnostics) {
      err = writer(&diagnostic_msgs_msg_dds__DiagnosticArray__desc, base + "diagnostics", diag, diag_w_);
    }
    dds_delete_qos(state);
    dds_delete_qos(diag);
    if (err.empty() && dev_.commands != nullptr) err = createCommandReader(base + "command");
    if (err.empty() && opt_.announce) {
      dds_qos_t* q = announceQos(false);
      err = writer(&phalanx_msgs_msg_dds__DeviceAnnouncement__desc, kDevicesTopic, q, announce_w_);
      dds_delete_qos(q);
      char host[256] = {};
      gethostname(host, sizeof host - 1);
      host_ = host;
    }
    joint_frame_ = frame_prefix_ + "base";
    for (uint8_t j = 0; j < names_.joint_count; ++j) joint_names_[j] = const_cast<char*>(names_.joints[j]);
    return err;
  }

  /// Commands (docs/dds.md §"Commands"): reliable, volatile, keep-last commands.depth; a wait set on its own
  /// thread.
  std::string createCommandReader(const std::string& name) {
    dds_qos_t* q = makeQos(true, opt_.command_depth);
    const dds_entity_t t = dds_create_topic(participant_, &phalanx_msgs_msg_dds__Command__desc, name.c_str(), q, nullptr);
    std::string err;
    if (t < 0) err = "dds: cannot create topic " + name + ": " + dds_strretcode(t);
    if (err.empty()) {
      cmd_r_ = dds_create_reader(participant_, t, q, nullptr);
      if (cmd_r_ < 0) err = "dds: cannot create the reader of " + name + ": " + dds_strretcode(cmd_r_);
    }
    dds_delete_qos(q);
    if (!err.empty()) return err;
    waitset_ = dds_create_waitset(participant_);
    const dds_entity_t rc = dds_create_readcondition(cmd_r_, DDS_ANY_STATE);
    if (waitset_ < 0 || rc < 0 || dds_waitset_attach(waitset_, rc, 0) != DDS_RETCODE_OK) {
      return "dds: cannot wait on the reader of " + name;
    }
    command_topic_ = name;
    return {};
  }

  void serveCommands() {
    // Threads inherit the loop's scheduling; the network side never competes with it.
    sched_param normal{};
    pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);
    constexpr int kBatch = 32;
    void* samples[kBatch] = {};
    dds_sample_info_t infos[kBatch];
    while (running_.load(std::memory_order_relaxed)) {
      dds_waitset_wait(waitset_, nullptr, 0, DDS_MSECS(100));
      for (;;) {
        const dds_return_t n = dds_take(cmd_r_, samples, infos, kBatch, kBatch);  // loaned samples
        if (n <= 0) break;
        for (dds_return_t i = 0; i < n; ++i) {
          onCommand(*static_cast<const phalanx_msgs_msg_dds__Command_*>(samples[i]), infos[i]);
        }
        dds_return_loan(cmd_r_, samples, n);
      }
    }
  }

  /// How many values a command of this kind carries (0: a kind the client path refuses; any length passes).
  size_t expectedValues(uint8_t kind) const {
    switch (static_cast<client_wire::CommandKind>(kind)) {
      case client_wire::CommandKind::kRaw: return dev_.layout->setpoint_count;
      case client_wire::CommandKind::kGloveFingertipForce: return 10;
      case client_wire::CommandKind::kSeaFingerTorque: return 2;
      case client_wire::CommandKind::kPenWrench: return 6;
      default: return 0;
    }
  }

  /// One sample: the writer that first commands holds the device (the client channel's one-commander rule);
  /// its commands go into the command block as a socket client's would. Validation of values, mode and kind,
  /// the limits, the deadline and the force-off are the client path's (ClientPort), not repeated here.
  void onCommand(const phalanx_msgs_msg_dds__Command_& m, const dds_sample_info_t& info) {
    if (!info.valid_data) {  // the holder's writer went away: deleted (disposed, a hand-back) or lost (lease)
      if (generation_ != 0 && info.publication_handle == holder_) {
        if (info.instance_state == DDS_IST_NOT_ALIVE_DISPOSED) dev_.commands->releaseInProcess(generation_);
        else dev_.commands->goneInProcess(generation_);
        generation_ = 0;
        holder_ = 0;
      }
      return;
    }
    ++cmd_received_;
    const size_t want = expectedValues(m.kind);
    if (m.values._length > client_wire::kMaxModelValues || (want != 0 && m.values._length != want)) {
      ++cmd_malformed_;
      cmd_last_refusal_ = "kind " + std::to_string(m.kind) + " carries " + std::to_string(want) + " values, got " +
                          std::to_string(m.values._length);
      return;
    }
    if (generation_ == 0) {
      std::string why;
      const auto fb = opt_.command_fallback == "transparent" ? client_wire::Fallback::kTransparent
                                                             : client_wire::Fallback::kSafe;
      generation_ = dev_.commands->attachInProcess(opt_.command_deadline_ms, fb, client::CommandSource::kDds, why);
      if (generation_ == 0) {
        ++cmd_refused_busy_;
        cmd_last_refusal_ = why;
        return;
      }
      holder_ = info.publication_handle;
    } else if (info.publication_handle != holder_) {
      ++cmd_other_writer_;
      cmd_last_refusal_ = "another DDS writer holds this device";
      return;
    }
    client_wire::CommandPayload p{};
    p.generation = generation_;
    p.command_seq = ++command_seq_;
    p.mode = m.mode;
    p.kind = static_cast<client_wire::CommandKind>(m.kind);
    bool finite = true;
    float* dst = p.kind == client_wire::CommandKind::kRaw ? p.setpoint : p.model;
    for (uint32_t i = 0; i < m.values._length; ++i) {
      dst[i] = m.values._buffer[i];
      finite = finite && std::isfinite(dst[i]);
    }
    if (!finite) ++cmd_nonfinite_;  // passed on: the client path refuses and counts it
    dev_.commands->writeInProcess(p);
    ++cmd_accepted_;
  }

  nlohmann::json commandsJson() const {
    if (cmd_r_ <= 0) return {{"enabled", false}};
    return {{"enabled", true},
            {"topic", command_topic_},
            {"deadline_ms", opt_.command_deadline_ms},
            {"received", cmd_received_},
            {"passed_to_client_path", cmd_accepted_},
            {"nonfinite_passed", cmd_nonfinite_},
            {"refused_malformed", cmd_malformed_},
            {"refused_busy", cmd_refused_busy_},
            {"refused_other_writer", cmd_other_writer_},
            {"last_refusal", cmd_last_refusal_}};
  }

  /// This device on rt/phalanx/devices: at start, about once a second, and "stopped" at the end.
  void announce(const std::string& state) {
    if (announce_w_ <= 0) return;
    phalanx_msgs_msg_dds__DeviceAnnouncement_ m{};
    m.stamp = stamp(clockNs(CLOCK_MONOTONIC));
    const std::string spec = dev_.device_spec;
    m.host = text(host_);
    m.name = text(ns_);
    m.device_type = const_cast<char*>(dev_.layout->name);
    m.device_spec = text(spec);
    m.state = text(state);
    m.rate_hz = dev_.rate_hz;
    m.firmware_build_id = dev_.firmware_build_id;
    m.commands = dev_.commands != nullptr;
    check(dds_write(announce_w_, &m));
    ++announcements_;
  }

  void announceDue() {
    const uint64_t now = clockNs(CLOCK_MONOTONIC);
    if (now < next_announce_ns_) return;
    next_announce_ns_ = now + 1000000000ull;
    if (!seen_sample_) announce("starting");
    else if (last_faults_ != 0) announce("fault: " + faultList(last_faults_));
    else announce(std::string("running (") + modeName(last_mode_) + ")");
  }

  void serve() {
    LoopSample s;
    while (running_.load(std::memory_order_relaxed)) {
      if (port_.take(s, 100)) handle(s);
      announceDue();
    }
    while (port_.take(s, 0)) handle(s);  // after stop(): what is still queued is published
  }

  void handle(const LoopSample& s) {
    seen_sample_ = true;
    last_faults_ = s.tel.fault_bits;
    last_mode_ = s.tel.mode;
    if ((s.what & kState) != 0) publishState(s);
    if ((s.what & kDiagnostics) != 0) publishDiagnostics(s);
  }

  builtin_interfaces_msg_dds__Time_ stamp(uint64_t mono_ns) const {
    const int64_t t = static_cast<int64_t>(mono_ns) + offset_ns_;
    return {static_cast<int32_t>(t / 1000000000LL), static_cast<uint32_t>(t % 1000000000LL)};
  }

  void check(dds_return_t rc) {
    if (rc != DDS_RETCODE_OK) ++write_errors_;
  }

  /// Header stamp: the telemetry's arrival at the host (CLOCK_MONOTONIC mapped onto CLOCK_REALTIME at start).
  void publishState(const LoopSample& s) {
    stage_->observe(s.tel);  // the client channel's device-model stage, on this thread (its own instance)
    modelView(*dev_.layout, *stage_, s.tel, ms_);
    const builtin_interfaces_msg_dds__Time_ st = stamp(s.tel.host_rx_ns);
    if (joints_w_ > 0) {
      sensor_msgs_msg_dds__JointState_ m{};
      m.header = {st, text(joint_frame_)};
      m.name = {ms_.joint_count, ms_.joint_count, joint_names_.data(), false};
      m.position = {ms_.joint_count, ms_.joint_count, ms_.position.data(), false};
      if (ms_.has_effort) m.effort = {ms_.joint_count, ms_.joint_count, ms_.effort.data(), false};
      check(dds_write(joints_w_, &m));
    }
    for (uint8_t b = 0; b < ms_.body_count; ++b) {
      if (pose_w_[b] > 0) {
        const ModelPose& p = ms_.pose[b];
        geometry_msgs_msg_dds__PoseStamped_ m{};
        m.header = {st, text(pose_frame_[b])};
        m.pose.position = {p.position[0], p.position[1], p.position[2]};
        m.pose.orientation = {p.orientation[0], p.orientation[1], p.orientation[2], p.orientation[3]};
        check(dds_write(pose_w_[b], &m));
      }
      if (wrench_w_[b] > 0) {
        const ModelWrench& w = ms_.wrench[b];
        geometry_msgs_msg_dds__WrenchStamped_ m{};
        m.header = {st, text(wrench_frame_[b])};
        m.wrench.force = {w.force[0], w.force[1], w.force[2]};
        m.wrench.torque = {w.torque[0], w.torque[1], w.torque[2]};
        check(dds_write(wrench_w_[b], &m));
      }
    }
    ++state_samples_;
    to_written_us_.add(static_cast<double>(clockNs(CLOCK_MONOTONIC) - s.tel.host_rx_ns) / 1000.0);
  }

  /// One status: the loop's figures and the device's faults. Level ERROR while a fault is latched, WARN when
  /// periods were missed or samples dropped since the last one, else OK.
  void publishDiagnostics(const LoopSample& s) {
    const uint64_t dropped = port_.droppedFull();
    uint8_t level = 0;
    std::string message = "running";
    if (s.tel.fault_bits != 0) {
      level = 2;
      message = "fault latched: " + faultList(s.tel.fault_bits);
    } else if (s.overruns > last_overruns_ || dropped > last_dropped_) {
      level = 1;
      message = "missed periods or dropped DDS samples since the last status";
    }
    last_overruns_ = s.overruns;
    last_dropped_ = dropped;
    const std::vector<std::pair<std::string, std::string>> kv = {
        {"cycle", std::to_string(s.cycle)},
        {"rate_hz", std::to_string(dev_.rate_hz)},
        {"missed_periods", std::to_string(s.overruns)},
        {"period_jitter_us", std::to_string(s.jitter_us)},
        {"cycle_time_us", std::to_string(s.cycle_us)},
        {"telemetry_seq", std::to_string(s.tel.seq)},
        {"device_time_us", std::to_string(s.tel.device_time_us)},
        {"mode", modeName(s.tel.mode)},
        {"fault_bits", std::to_string(s.tel.fault_bits)},
        {"faults", faultList(s.tel.fault_bits)},
        {"dds_dropped", std::to_string(dropped)},
        {"dds_state_samples", std::to_string(state_samples_)}};
    std::vector<diagnostic_msgs_msg_dds__KeyValue_> values;
    values.reserve(kv.size());
    for (const auto& [k, v] : kv) values.push_back({text(k), text(v)});
    const std::string name = ns_ + "/loop";
    const std::string hw = std::string(dev_.layout->name) + " " + dev_.device_spec + " firmware " +
                           std::to_string(dev_.firmware_build_id);
    diagnostic_msgs_msg_dds__DiagnosticStatus_ st{};
    st.level = level;
    st.name = text(name);
    st.message = text(message);
    st.hardware_id = text(hw);
    st.values = {static_cast<uint32_t>(values.size()), static_cast<uint32_t>(values.size()), values.data(), false};
    diagnostic_msgs_msg_dds__DiagnosticArray_ m{};
    m.header = {stamp(s.tel.host_rx_ns), text(joint_frame_)};
    m.status = {1, 1, &st, false};
    check(dds_write(diag_w_, &m));
    ++diag_samples_;
  }

  DdsOptions opt_;
  BridgeDevice dev_;
  LoopPort& port_;
  std::unique_ptr<client::DeviceModelStage> stage_;
  ModelNames names_;
  std::string ns_, frame_prefix_, joint_frame_;
  dds_entity_t domain_ = 0, participant_ = 0, joints_w_ = 0, diag_w_ = 0;
  std::array<dds_entity_t, ModelState::kMaxBodies> pose_w_{}, wrench_w_{};
  std::array<std::string, ModelState::kMaxBodies> pose_frame_, wrench_frame_;
  std::array<char*, ModelState::kMaxJoints> joint_names_{};
  ModelState ms_{};
  int64_t offset_ns_ = 0;
  std::atomic<bool> running_{false};
  std::thread thread_, cmd_thread_;
  dds_entity_t announce_w_ = 0;
  std::string host_;
  uint64_t next_announce_ns_ = 0, announcements_ = 0;
  bool seen_sample_ = false;
  uint16_t last_faults_ = 0;
  protocol::Mode last_mode_ = protocol::Mode::kSafe;
  dds_entity_t cmd_r_ = 0, waitset_ = 0;
  std::string command_topic_, cmd_last_refusal_;
  dds_instance_handle_t holder_ = 0;  ///< the publication that holds the device (0: none)
  uint32_t generation_ = 0, command_seq_ = 0;
  uint64_t cmd_received_ = 0, cmd_accepted_ = 0, cmd_nonfinite_ = 0, cmd_malformed_ = 0, cmd_refused_busy_ = 0,
           cmd_other_writer_ = 0;  // command thread only; read by summaryJson() after stop()
  uint64_t state_samples_ = 0, diag_samples_ = 0, write_errors_ = 0, last_overruns_ = 0, last_dropped_ = 0;
  Histogram to_written_us_{20000};
};

}  // namespace

bool bridgeAvailable() { return true; }

std::unique_ptr<Bridge> startBridge(const DdsOptions& o, const BridgeDevice& dev, LoopPort& port, std::string& error) {
  auto b = std::make_unique<CycloneBridge>(o, dev, port);
  error = b->start();
  if (!error.empty()) return nullptr;
  return b;
}

}  // namespace phalanx::host::dds
