#pragma once
/// Session recorder: the 1 kHz loop hands each cycle to a bounded lock-free queue (never blocks, never
/// allocates); a writer thread frames, checksums and appends them to the file and write(2)s at least every
/// flush_period_ms, so a `kill -9` of the daemon loses at most that much (data handed to the kernel survives
/// the process). fdatasync every sync_period_ms bounds the loss on power failure too.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/record/record_format.h"
#include "phalanx/host/record/spsc_queue.h"

namespace phalanx::host::record {

/// An event raised in the real-time loop: plain data, formatted to JSON by the writer thread.
struct LoopEvent {
  enum class Kind : uint8_t {
    kDeviceEvent = 1,      ///< a device Event message: code, channel, detail, value
    kExerciseStarted = 2,  ///< code = therapy::ExerciseId
    kLimitActive = 3,      ///< code = bit per channel whose effort the patient limits changed (onset only)
    kFaultBits = 4,        ///< code = telemetry fault bits, when they change
  };
  double t_s = 0.0;
  Kind kind = Kind::kDeviceEvent;
  uint16_t code = 0;
  uint8_t channel = 0;
  uint8_t detail = 0;
  float value = 0.0f;
};

struct WriterConfig {
  /// Queue depth in cycles: 4096 = 4 s at 1 kHz of writer stall before a cycle is dropped (drops are counted
  /// and recorded as a "record-gap" event).
  std::size_t queue_cycles = 4096;
  /// 20 ms: five flushes inside the 100 ms loss budget of a kill -9 (docs/records.md).
  unsigned flush_period_ms = 20;
  /// fdatasync period: bounds the loss on power failure / kernel crash, at the cost of disk writes.
  unsigned sync_period_ms = 1000;
};

class RecordWriter {
 public:
  explicit RecordWriter(const WriterConfig& config = {});
  ~RecordWriter();
  RecordWriter(const RecordWriter&) = delete;
  RecordWriter& operator=(const RecordWriter&) = delete;

  /// Create the file (refuses to overwrite), write magic + header, start the writer thread. "" or an error.
  std::string open(const std::string& path, const nlohmann::json& header);
  bool isOpen() const { return fd_ >= 0; }
  /// Real-time side (one producer thread): enqueue a cycle. Never blocks; false when the queue was full.
  bool pushCycle(const CycleRecord& cycle);
  /// Real-time side (same producer thread as pushCycle): never blocks; false when its queue was full.
  bool pushLoopEvent(const LoopEvent& event);
  /// Any thread, not real time: an event record {"t_s": …, "kind": kind, …fields}.
  void pushEvent(double t_s, const std::string& kind, nlohmann::json fields = nlohmann::json::object());
  /// Drain everything, write the footer (if not null), fsync and close. Idempotent.
  void close(const nlohmann::json& footer = nullptr);

  uint64_t cyclesWritten() const { return cycles_written_.load(); }
  uint64_t cyclesDropped() const { return dropped_.load(); }
  const std::string& path() const { return path_; }
  /// First write error ("" while none).
  std::string error() const;

 private:
  void run();
  bool drainOnce();  // true if anything was written
  void writeBytes(const std::vector<uint8_t>& bytes);

  WriterConfig config_;
  SpscQueue<CycleRecord> queue_;
  SpscQueue<LoopEvent> loop_events_{256};
  std::string path_;
  int fd_ = -1;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> cycles_written_{0};
  std::atomic<uint64_t> dropped_{0};
  uint64_t dropped_reported_ = 0;
  mutable std::mutex mutex_;  // guards events_, error_, cv_
  std::condition_variable cv_;
  std::vector<std::vector<uint8_t>> events_;
  std::string error_;
  std::vector<uint8_t> buffer_;
};

}  // namespace phalanx::host::record
