#pragma once
/// CSV recorder of a session (`--record FILE.csv`). The loop only copies each cycle into a bounded lock-free queue
/// (no formatting, no system call, no allocation); a writer thread at normal priority formats the rows and writes
/// them. Before this the loop formatted every row into a 1 MiB stdio buffer and, whenever it filled (every ~3 s),
/// made the 1 MiB write(2) itself: on a machine with busy disks that write blocked the loop for up to 28 ms
/// (docs/modbus.md, "Measured"). A full queue (the writer starved for kQueueRows cycles) drops the row; drops are
/// counted in the summary.
///
/// A failing disk (full, read-only, I/O error): the writer latches the first write/fsync/close error, logs it on
/// stderr at once, cuts the file back to its last whole row and writes nothing more. failed() (real time: one
/// atomic load) tells the loop; rowsWritten() + rowsLost() account for every row the loop gave (docs/records.md,
/// "When the records disk fails").
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include "phalanx/host/record/mcap_session.h"
#include "phalanx/host/record/spsc_queue.h"
#include "phalanx/host/record/write_failure.h"
#include "phalanx/host/session.h"
#include "phalanx/protocol/devices.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::host::record {

/// `--record FILE` recorder: CSV (named columns with units, the default) or, for a FILE ending in ".mcap", MCAP
/// (mcap_session.h's channels; one zstd chunk per ≤ 50 ms, so a kill -9 loses at most that; the summary is
/// written at close()). Both go through the same queue, writer thread and failure accounting; a "row" of an
/// MCAP file is one cycle, written when its whole chunk reached the file.
/// What a recording holds besides the cycles (docs/records.md, "Replay").
struct RecordingContext {
  bool sync_column = false;  ///< CSV: the sync_pulses column
  /// MCAP: the header's "replay" object (record/replay.h replayConfig); null: the file cannot be replayed.
  nlohmann::json replay;
  /// pantograph: the geometry the pen channels / columns use (null: pen::defaultModel).
  const phalanx::pen::Model<double>* pen_model = nullptr;
};

class CsvRecorder {
 public:
  ~CsvRecorder() { close(); }
  /// Create the file and write its header; starts the writer thread. "" or the problem.
  std::string open(const std::string& path, const protocol::DeviceLayout& layout, const RecordingContext& context);
  std::string open(const std::string& path, const protocol::DeviceLayout& layout, bool sync_column) {
    RecordingContext c;
    c.sync_column = sync_column;
    return open(path, layout, c);
  }
  /// Loop side: one copy into the queue (after a failure: only counted as lost). source: CommandExtras::source.
  void row(double t_s, const TelemetryFrame& tel, const protocol::Command& cmd, uint64_t sync_pulses,
           uint8_t source = 0);
  /// Writes what is queued, fsyncs and closes (a failure there is latched too). Idempotent.
  void close();

  /// Real time: writing the file failed; nothing is written after it.
  bool failed() const { return failure_.failed(); }
  /// "" or the first error, naming the file ("recording X: writing failed: No space left on device (…)").
  std::string error() const { return failure_.error(); }
  /// Rows (after the header) whose every byte reached the file. Exact after close().
  uint64_t rowsWritten() const { return written_.load(); }
  /// Rows given to row() that are not in the file: dropped by a full queue, or not written after a failure.
  /// Exact after close(); rowsWritten() + rowsLost() = every row() call.
  uint64_t rowsLost() const { return dropped_.load() + unwritten_.load(); }
  /// Rows refused by a full queue (part of rowsLost()).
  uint64_t rowsDropped() const { return dropped_.load(); }
  /// The summary's names: rows = rowsWritten(), dropped = rowsLost().
  uint64_t rows() const { return rowsWritten(); }
  uint64_t dropped() const { return rowsLost(); }

 private:
  /// 8 s at 1 kHz of writer starvation before a row is dropped; ≈ 1.4 MB.
  static constexpr size_t kQueueRows = 8192;
  /// Rows formatted before each write(2): ~100 ms of recording at 1 kHz (a crash loses at most that much).
  static constexpr size_t kRowsPerWrite = 100;
  /// MCAP: a chunk is written before it would hold this much session time (or at kRowsPerWrite rows).
  static constexpr double kMcapChunkS = 0.05;
  struct Row {
    double t_s = 0.0;
    uint64_t device_time_us = 0, sync_pulses = 0;
    uint16_t seq = 0, cmd_seq_echo = 0, fault_bits = 0, cmd_seq = 0;
    uint8_t mode = 0, cmd_mode = 0, state_flags = 0, source = 0;
    std::array<float, protocol::kMaxSamples> sample{};
    std::array<float, protocol::kMaxSetpoints> setpoint{};
    std::array<uint16_t, protocol::kMaxSetpoints> gain_permille{};
  };
  void formatMcap(const Row& r);
  void writerMain();
  void format(const Row& r);
  /// Writes the formatted rows (none after a failure) and counts them.
  void writePending();
  void countLost(uint64_t n) { dropped_.store(dropped_.load(std::memory_order_relaxed) + n, std::memory_order_relaxed); }

  int fd_ = -1;
  std::string path_;
  uint8_t samples_ = 0;
  uint8_t setpoints_ = 0;
  bool sync_column_ = false;
  bool pen_ = false;                 // pantograph: the CSV's pen columns
  phalanx::pen::Model<double> pen_model_{};
  // Loop thread only writes dropped_ (queue full, or after a failure); the writer thread written_/unwritten_.
  std::atomic<uint64_t> dropped_{0};
  std::atomic<uint64_t> written_{0};
  std::atomic<uint64_t> unwritten_{0};
  WriteFailure failure_;
  std::string pending_;        // formatted rows not yet written (writer thread)
  uint64_t pending_rows_ = 0;
  uint64_t file_bytes_ = 0;    // whole rows (and the header) in the file
  // MCAP output (null for CSV): the encoder, the CRC of every byte in the file, the first pending row's time.
  std::unique_ptr<McapSession> mcap_;
  // Wall clock of t_s = 0, taken by the loop at its first row (one vDSO clock read, no system call); the queue's
  // release/acquire hands it to the writer with that row.
  uint64_t epoch_ns_ = 0;
  bool first_row_ = true;
  uint32_t file_crc_ = 0;
  double pending_t0_ = 0.0;
  void writeMcapChunk();
  std::unique_ptr<SpscQueue<Row>> queue_;
  std::atomic<bool> running_{false};
  std::thread writer_;
};

}  // namespace phalanx::host::record
