#pragma once
/// Session recorder: the 1 kHz loop hands each cycle to a bounded lock-free queue (never blocks, never
/// allocates); a writer thread frames, checksums and appends them to the file and write(2)s at least every
/// flush_period_ms, so a `kill -9` of the daemon loses at most that much (data handed to the kernel survives
/// the process). fdatasync every sync_period_ms bounds the loss on power failure too. A failing disk (full,
/// read-only, I/O error) is latched at its first error (failed(), error(), logged on stderr at once), nothing is
/// written after it and every cycle that is not in the file is counted (cyclesLost()).
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
#include "phalanx/host/record/write_failure.h"

namespace phalanx::host::record {

/// An event raised in the real-time loop: plain data, formatted to JSON by the writer thread.
struct LoopEvent {
  enum class Kind : uint8_t {
    kDeviceEvent = 1,      ///< a device Event message: code, channel, detail, value
    kExerciseStarted = 2,  ///< code = therapy::ExerciseId
    kLimitActive = 3,      ///< code = bit per channel whose effort the patient limits changed (onset only)
    kFaultBits = 4,        ///< code = telemetry fault bits, when they change
    kPlanStepEnded = 5,    ///< session plan: code = step index, detail = 1 duration / 2 repetitions reached,
                           ///< value = the step's counted seconds, count = its repetitions
  };
  double t_s = 0.0;
  Kind kind = Kind::kDeviceEvent;
  uint16_t code = 0;
  uint8_t channel = 0;
  uint8_t detail = 0;
  float value = 0.0f;
  uint32_t count = 0;
};

struct WriterConfig {
  /// Queue depth in cycles: 4096 = 4 s at 1 kHz of writer stall before a cycle is dropped (drops are counted
  /// and recorded as a "record-gap" event).
  std::size_t queue_cycles = 4096;
  /// 20 ms: five flushes inside the 100 ms loss budget of a kill -9 (docs/records.md).
  unsigned flush_period_ms = 20;
  /// fdatasync period: bounds the loss on power failure / kernel crash, at the cost of disk writes.
  unsigned sync_period_ms = 1000;
  /// Cycles of each flush as one compressed cycle block (record type 5, format version 2: ≈ 2.3× smaller,
  /// docs/records.md "Storage"); a damaged block then costs its ≤ 20 ms of cycles instead of one. Session records
  /// of the daemon use it (TherapySessionConfig); false writes one plain cycle record per cycle (format 1).
  bool cycle_blocks = false;
};

class RecordWriter {
 public:
  explicit RecordWriter(const WriterConfig& config = {});
  ~RecordWriter();
  RecordWriter(const RecordWriter&) = delete;
  RecordWriter& operator=(const RecordWriter&) = delete;

  /// Create the file (O_EXCL, mode 0640: refuses to overwrite) and nothing else yet, so an unwritable records
  /// directory is found before a session starts. "" or an error naming the file; err_no (if given) gets the
  /// errno (EEXIST: the name is taken).
  std::string create(const std::string& path, int* err_no = nullptr);
  /// Write magic + header into the created file and start the writer thread. "" or an error (the file is then
  /// failed(); discard() removes it).
  std::string start(const nlohmann::json& header);
  /// create() + start().
  std::string open(const std::string& path, const nlohmann::json& header);
  /// Close and remove a file that was created but never started (the session ended before its first cycle).
  void discard();
  bool isOpen() const { return fd_ >= 0; }
  bool started() const { return started_; }
  /// Real-time side (one producer thread): enqueue a cycle. Never blocks; false when the queue was full.
  bool pushCycle(const CycleRecord& cycle);
  /// Real-time side (same producer thread as pushCycle): never blocks; false when its queue was full.
  bool pushLoopEvent(const LoopEvent& event);
  /// Any thread, not real time: an event record {"t_s": …, "kind": kind, …fields}.
  void pushEvent(double t_s, const std::string& kind, nlohmann::json fields = nlohmann::json::object());
  /// Drain everything, write the footer (if not null and nothing failed), fsync and close. Idempotent.
  void close(const nlohmann::json& footer = nullptr);

  /// Cycles whose every byte reached the file.
  uint64_t cyclesWritten() const { return cycles_written_.load(); }
  /// Cycles refused by a full queue (also counted in cyclesLost()).
  uint64_t cyclesDropped() const { return dropped_.load(); }
  /// Cycles given to pushCycle that are not in the file: dropped on a full queue, or not written (whole) after
  /// a write error. Exact once close() returned (cycles still queued are not counted before).
  uint64_t cyclesLost() const { return dropped_.load() + cycles_unwritten_.load(); }
  const std::string& path() const { return path_; }
  /// Real time (one atomic load): a write, fdatasync or close of the file failed; nothing is written after it.
  bool failed() const { return failure_.failed(); }
  /// The first write error ("" while none), e.g. "session record X: writing failed: No space left on device …".
  std::string error() const { return failure_.error(); }

 private:
  void run();
  bool drainOnce();  // true if anything was written
  /// Frames one record into buffer_ and notes where it ends.
  void add(RecordType type, const uint8_t* payload, std::size_t length, std::size_t cycles = 0);
  /// The cycles gathered in block_ as one compressed cycle block (plain cycle records if it does not compress).
  void addBlock();
  /// Writes buffer_ (nothing after a failure); counts its whole cycles as written or unwritten; on an error
  /// latches it and cuts the file back to the last whole record.
  void writeBuffer();
  void fail(const std::string& what);

  WriterConfig config_;
  SpscQueue<CycleRecord> queue_;
  SpscQueue<LoopEvent> loop_events_{256};
  std::string path_;
  int fd_ = -1;
  bool started_ = false;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> cycles_written_{0};
  std::atomic<uint64_t> cycles_unwritten_{0};
  std::atomic<uint64_t> dropped_{0};
  std::atomic<uint64_t> loop_events_dropped_{0};
  uint64_t dropped_reported_ = 0;
  uint64_t file_bytes_ = 0;  // bytes in the file that are whole records (writer thread; open/close before/after it)
  mutable std::mutex mutex_;  // guards events_, cv_
  std::condition_variable cv_;
  std::vector<std::vector<uint8_t>> events_;
  WriteFailure failure_;
  std::vector<uint8_t> buffer_;
  std::vector<std::size_t> record_ends_;  // end offset in buffer_ of each record
  std::vector<std::size_t> cycle_ends_;   // … of each cycle (a block's cycles all end where it ends)
  std::vector<uint8_t> block_;            // encoded cycles of the block being gathered (writer thread)
  uint16_t block_count_ = 0, block_length_ = 0;
};

}  // namespace phalanx::host::record
