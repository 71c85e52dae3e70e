#pragma once
/// CSV recorder of a session (`--record FILE.csv`). The loop only copies each cycle into a bounded lock-free queue
/// (no formatting, no system call, no allocation); a writer thread at normal priority formats the rows and writes
/// them. Before this the loop formatted every row into a 1 MiB stdio buffer and, whenever it filled (every ~3 s),
/// made the 1 MiB write(2) itself: on a machine with busy disks that write blocked the loop for up to 28 ms
/// (docs/modbus.md, "Measured"). A full queue (the writer starved for kQueueRows cycles) drops the row; drops are
/// counted in the summary.
#include <array>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <thread>

#include "phalanx/host/record/spsc_queue.h"
#include "phalanx/host/session.h"
#include "phalanx/protocol/devices.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::host::record {

class CsvRecorder {
 public:
  ~CsvRecorder() { close(); }
  /// Create the file and write its header; starts the writer thread. "" or the problem.
  std::string open(const std::string& path, const protocol::DeviceLayout& layout, bool sync_column);
  /// Loop side: one copy into the queue.
  void row(double t_s, const TelemetryFrame& tel, const protocol::Command& cmd, uint64_t sync_pulses);
  void close();
  uint64_t rows() const { return rows_; }
  uint64_t dropped() const { return dropped_; }

 private:
  /// 8 s at 1 kHz of writer starvation before a row is dropped; ≈ 1.4 MB.
  static constexpr size_t kQueueRows = 8192;
  struct Row {
    double t_s = 0.0;
    uint64_t device_time_us = 0, sync_pulses = 0;
    uint16_t seq = 0, cmd_seq_echo = 0, fault_bits = 0;
    uint8_t mode = 0;
    std::array<float, protocol::kMaxSamples> sample{};
    std::array<float, protocol::kMaxSetpoints> setpoint{};
  };
  void writerMain();
  void format(const Row& r);

  std::FILE* f_ = nullptr;
  uint8_t samples_ = 0;
  uint8_t setpoints_ = 0;
  bool sync_column_ = false;
  uint64_t rows_ = 0, dropped_ = 0;
  std::unique_ptr<SpscQueue<Row>> queue_;
  std::atomic<bool> running_{false};
  std::thread writer_;
};

}  // namespace phalanx::host::record
