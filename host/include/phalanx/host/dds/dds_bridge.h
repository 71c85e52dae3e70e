#pragma once
/// phalanxd's DDS bridge (docs/dds.md): ROS 2-compatible topics over Cyclone DDS, published by a thread of its
/// own. The 1 kHz loop only calls LoopPort::offer(): a copy into a preallocated single-producer/single-consumer
/// ring and a semaphore post, never a wait; when the bridge falls behind the ring is full, the sample is dropped
/// and counted (summary dds.dropped_full), and the loop never slows.
#include <semaphore.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "phalanx/host/client/model_geometry.h"
#include "phalanx/host/dds/dds_options.h"
#include "phalanx/host/record/spsc_queue.h"
#include "phalanx/host/session.h"
#include "phalanx/protocol/devices.h"

namespace phalanx::host::client {
class Server;
}

namespace phalanx::host::dds {

/// What the loop hands over: the telemetry and the loop's own figures at that cycle.
struct LoopSample {
  TelemetryFrame tel;
  uint64_t wake_ns = 0;
  uint64_t cycle = 0;
  uint64_t overruns = 0;
  float jitter_us = 0.0f;
  float cycle_us = 0.0f;
  uint8_t what = 0;  ///< kState | kDiagnostics
};
inline constexpr uint8_t kState = 1;
inline constexpr uint8_t kDiagnostics = 2;

/// The loop's side. offer() is wait-free and allocation-free.
class LoopPort {
 public:
  LoopPort(const DdsOptions& o, unsigned rate_hz);
  ~LoopPort();
  LoopPort(const LoopPort&) = delete;
  LoopPort& operator=(const LoopPort&) = delete;

  /// Once per cycle after the send: hands the sample over when a state or a diagnostics publication is due
  /// (or the fault bits changed: diagnostics at once). A stale cycle (no new telemetry) hands over no state.
  void offer(const TelemetryFrame& tel, uint64_t wake_ns, uint64_t cycle, uint64_t overruns, double jitter_us,
             double cycle_us);
  /// Bridge thread: the next sample, waiting at most timeout_ms. false: none.
  bool take(LoopSample& out, int timeout_ms);
  uint64_t offered() const { return offered_.load(std::memory_order_relaxed); }
  uint64_t droppedFull() const { return dropped_.load(std::memory_order_relaxed); }
  uint64_t stateDecimation() const { return state_every_; }

 private:
  record::SpscQueue<LoopSample> ring_;
  sem_t ready_;
  uint64_t state_every_ = 1, diag_every_ = 1000;
  uint64_t next_state_cycle_ = 0, next_diag_cycle_ = 0;
  uint16_t last_faults_ = 0;
  uint64_t last_rx_ns_ = 0;
  std::atomic<uint64_t> offered_{0}, dropped_{0};
  LoopSample scratch_{};
};

/// The device the bridge speaks for.
struct BridgeDevice {
  const protocol::DeviceLayout* layout = nullptr;
  unsigned rate_hz = 1000;
  uint32_t firmware_build_id = 0;
  std::string device_spec;  ///< sim:glove5, serial:…, …
  client::ModelGeometry geometry;  ///< the device models' geometry (the same as the client channel's)
  client::Server* commands = nullptr;  ///< dds.commands: the client channel commands enter by (else none read)
};

/// The publishing side (Cyclone DDS). Created by startBridge().
class Bridge {
 public:
  virtual ~Bridge() = default;
  /// Stop the thread (publishing what is still queued) and delete the DDS entities.
  virtual void stop() = 0;
  virtual nlohmann::json summaryJson() const = 0;
};

/// Whether this phalanxd was built with Cyclone DDS.
bool bridgeAvailable();
/// Create the participant, topics and writers and start the thread; nullptr and error on failure.
std::unique_ptr<Bridge> startBridge(const DdsOptions& o, const BridgeDevice& dev, LoopPort& port, std::string& error);
/// rt/<ns>/… namespace for a device: o.ns, else phalanx/<device type>.
std::string topicNamespace(const DdsOptions& o, const protocol::DeviceLayout& layout);

}  // namespace phalanx::host::dds
