#include "phalanx/host/record/csv_recorder.h"

#include "phalanx/host/record/pen_channels.h"
#include "phalanx/host/therapy/device.h"

#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>

namespace phalanx::host::record {

std::string CsvRecorder::open(const std::string& path, const protocol::DeviceLayout& layout,
                              const RecordingContext& context) {
  const bool sync_column = context.sync_column;
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd_ < 0) return "cannot write recording " + path + ": " + std::strerror(errno);
  path_ = path;
  sync_column_ = sync_column;
  samples_ = layout.sample_count;
  setpoints_ = layout.setpoint_count;
  pen_ = layout.type == protocol::DeviceType::kPantograph;
  pen_model_ = context.pen_model != nullptr ? *context.pen_model : phalanx::pen::defaultModel<double>();
  const bool mcap = path.size() > 5 && path.compare(path.size() - 5, 5, ".mcap") == 0;
  std::string header;
  if (mcap) {
    McapLayout l;
    l.device = layout.name;
    l.samples = sampleColumnNames(layout);
    l.setpoints = setpointColumnNames(layout);
    l.start_epoch_ns = static_cast<uint64_t>(
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count());
    l.header = {{"device", layout.name}, {"samples", l.samples}, {"setpoints", l.setpoints}};
    if (!context.replay.is_null()) l.header["replay"] = context.replay;
    l.live = true;
    l.pen = pen_;
    l.pen_model = pen_model_;
    std::string err;
    mcap_ = std::make_unique<McapSession>(l, therapy::makeTherapyDevice(layout, {}, err));
    const std::vector<uint8_t> start = mcap_->start();
    header.assign(start.begin(), start.end());
    file_crc_ = mcapCrc(0, start.data(), start.size());
  } else {
    // Named columns with their units (docs/records.md, "--record CSV columns").
    header = "t_s,device_time_us,seq,cmd_seq_echo,mode,fault_bits";
    for (const auto& n : sampleColumnNames(layout)) header += "," + n;
    for (const auto& n : setpointColumnNames(layout)) header += "," + n;
    if (pen_) {
      for (const auto& n : penCsvColumns()) header += "," + n;
    }
    // Rising edges of the sync pulse emitted so far: the motion-capture frame index (docs/gpio.md).
    if (sync_column) header += ",sync_pulses";
    header += "\n";
  }
  int err_no = 0;
  if (writeFully(fd_, header.data(), header.size(), err_no) != header.size()) {
    const std::string err = "cannot write recording " + path + ": " + std::strerror(err_no);
    ::close(fd_);
    fd_ = -1;
    return err;
  }
  file_bytes_ = header.size();
  pending_.reserve(1 << 20);
  // Allocated and touched here, before the loop (and before mlockall, which then locks it).
  queue_ = std::make_unique<SpscQueue<Row>>(kQueueRows);
  running_ = true;
  writer_ = std::thread([this] { writerMain(); });
  return {};
}

void CsvRecorder::row(double t_s, const TelemetryFrame& tel, const protocol::Command& cmd, uint64_t sync_pulses,
                      uint8_t source) {
  if (!queue_) return;
  if (failed()) {
    countLost(1);
    return;
  }
  if (first_row_) {
    first_row_ = false;
    const auto now = std::chrono::duration_cast<std::chrono::nanoseconds>(
        std::chrono::system_clock::now().time_since_epoch()).count();
    epoch_ns_ = static_cast<uint64_t>(now - std::llround(t_s * 1e9));
  }
  Row r;
  r.t_s = t_s;
  r.device_time_us = tel.device_time_us;
  r.sync_pulses = sync_pulses;
  r.seq = tel.seq;
  r.cmd_seq_echo = tel.cmd_seq_echo;
  r.fault_bits = tel.fault_bits;
  r.mode = static_cast<uint8_t>(tel.mode);
  r.cmd_mode = static_cast<uint8_t>(cmd.mode);
  r.cmd_seq = cmd.seq;
  r.state_flags = tel.state_flags;
  r.source = source;
  std::copy(tel.value.begin(), tel.value.begin() + samples_, r.sample.begin());
  std::copy(cmd.setpoint, cmd.setpoint + setpoints_, r.setpoint.begin());
  std::copy(cmd.gain_scale_permille, cmd.gain_scale_permille + setpoints_, r.gain_permille.begin());
  if (!queue_->push(r)) countLost(1);
}

void CsvRecorder::close() {
  if (writer_.joinable()) {
    running_ = false;
    writer_.join();
  }
  queue_.reset();
  if (fd_ < 0) return;
  if (mcap_ && !failed()) {
    // The summary: only for a file whose every chunk reached it (a failed file stays readable as it was cut).
    const std::vector<uint8_t> tail = mcap_->finish(file_bytes_, file_crc_);
    int err_no = 0;
    const std::size_t done = writeFully(fd_, tail.data(), tail.size(), err_no);
    if (err_no != 0) {
      if (::ftruncate(fd_, static_cast<off_t>(file_bytes_)) != 0) file_bytes_ += done;
      failure_.set("recording " + path_ + ": writing the MCAP summary failed: " + std::strerror(err_no) +
                   " (every chunk is in the file; readers that need the summary must scan it)");
    } else {
      file_bytes_ += done;
    }
  }
  if (!failed()) {
    if (const int e = syncData(fd_); e != 0) failure_.set("recording " + path_ + ": fdatasync failed: " + std::strerror(e));
  }
  if (::close(fd_) != 0 && !failed()) failure_.set("recording " + path_ + ": close failed: " + std::strerror(errno));
  fd_ = -1;
}

void CsvRecorder::writerMain() {
  // Created before the loop goes SCHED_FIFO; made explicit anyway: the writer must never compete with the loop.
  sched_param normal{};
  normal.sched_priority = 0;
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);
  Row r;
  for (;;) {
    const bool more = running_.load();
    size_t n = 0;
    while (queue_->pop(r)) {
      // An MCAP chunk is closed before the row that would take it past kMcapChunkS of session time, so a chunk
      // spans less than that however long the loop itself stalled between two rows.
      if (mcap_ && pending_rows_ > 0 && r.t_s - pending_t0_ >= kMcapChunkS) writePending();
      format(r);
      ++n;
      if (pending_rows_ >= kRowsPerWrite) writePending();
    }
    if (!more) break;
    if (n == 0) usleep(5000);
  }
  writePending();
}

void CsvRecorder::writeMcapChunk() {
  const uint64_t rows = pending_rows_;
  pending_rows_ = 0;
  const std::vector<uint8_t> chunk = mcap_->takeChunk(file_bytes_);
  if (failed()) {
    unwritten_.fetch_add(rows);
    return;
  }
  int err_no = 0;
  const std::size_t done = writeFully(fd_, chunk.data(), chunk.size(), err_no);
  if (err_no == 0) {
    written_.fetch_add(rows);
    file_bytes_ += done;
    file_crc_ = mcapCrc(file_crc_, chunk.data(), chunk.size());
    return;
  }
  // A chunk counts only whole: cut the file back to the end of the previous one.
  unwritten_.fetch_add(rows);
  if (::ftruncate(fd_, static_cast<off_t>(file_bytes_)) != 0) file_bytes_ += done;
  failure_.set("recording " + path_ + ": writing failed: " + std::strerror(err_no) + " (" +
               std::to_string(written_.load()) + " rows written; nothing after them is recorded)");
}

void CsvRecorder::writePending() {
  if (pending_rows_ == 0) return;
  if (mcap_) {
    writeMcapChunk();
    return;
  }
  const uint64_t rows = pending_rows_;
  pending_rows_ = 0;
  if (failed()) {
    unwritten_.fetch_add(rows);
    pending_.clear();
    return;
  }
  int err_no = 0;
  const std::size_t done = writeFully(fd_, pending_.data(), pending_.size(), err_no);
  // A row counts as written only with its newline; a partial row is cut off the file below.
  const std::size_t whole_end = done == 0 ? 0 : pending_.rfind('\n', done - 1) + 1;
  const auto whole = static_cast<uint64_t>(std::count(pending_.begin(), pending_.begin() + static_cast<long>(done), '\n'));
  written_.fetch_add(whole);
  unwritten_.fetch_add(rows - whole);
  pending_.clear();
  if (err_no == 0) {
    file_bytes_ += done;
    return;
  }
  if (::ftruncate(fd_, static_cast<off_t>(file_bytes_ + whole_end)) == 0) file_bytes_ += whole_end;
  failure_.set("recording " + path_ + ": writing failed: " + std::strerror(err_no) + " (" +
               std::to_string(written_.load()) + " rows written; nothing after them is recorded)");
}

void CsvRecorder::formatMcap(const Row& r) {
  CycleRecord c;
  c.host_ns = static_cast<uint64_t>(std::llround(r.t_s * 1e9)) + 1;  // the loop's wake-up, from t_s (never 0)
  c.t_s = r.t_s;
  c.device_time_us = r.device_time_us;
  c.tel_seq = r.seq;
  c.cmd_seq_echo = r.cmd_seq_echo;
  c.fault_bits = r.fault_bits;
  c.tel_mode = r.mode;
  c.cmd_mode = r.cmd_mode;
  c.cmd_seq = r.cmd_seq;
  c.state_flags = r.state_flags;
  c.sample_count = samples_;
  c.setpoint_count = setpoints_;
  c.sample = r.sample;
  c.setpoint = r.setpoint;
  CommandExtras extras;
  extras.source = r.source;
  extras.gain_permille = r.gain_permille;
  if (pending_rows_ == 0) pending_t0_ = r.t_s;
  if (written_.load() + pending_rows_ == 0) mcap_->setStartEpoch(epoch_ns_);
  mcap_->addCycle(c, &extras);
  ++pending_rows_;
}

void CsvRecorder::format(const Row& r) {
  if (mcap_) {
    formatMcap(r);
    return;
  }
  char buf[64];
  auto put = [&](int n) { pending_.append(buf, static_cast<std::size_t>(std::min<int>(n, sizeof buf - 1))); };
  put(std::snprintf(buf, sizeof buf, "%.6f,%llu,%u,%u,%u,%u", r.t_s, static_cast<unsigned long long>(r.device_time_us),
                    r.seq, r.cmd_seq_echo, static_cast<unsigned>(r.mode), r.fault_bits));
  for (uint8_t i = 0; i < samples_; ++i) put(std::snprintf(buf, sizeof buf, ",%.5g", static_cast<double>(r.sample[i])));
  for (uint8_t i = 0; i < setpoints_; ++i) put(std::snprintf(buf, sizeof buf, ",%.5g", static_cast<double>(r.setpoint[i])));
  if (pen_) appendPenCsv(pending_, measurePen(pen_model_, r.sample.data()));
  if (sync_column_) put(std::snprintf(buf, sizeof buf, ",%llu", static_cast<unsigned long long>(r.sync_pulses)));
  pending_.push_back('\n');
  ++pending_rows_;
}

}  // namespace phalanx::host::record
