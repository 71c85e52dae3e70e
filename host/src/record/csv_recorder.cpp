#include "phalanx/host/record/csv_recorder.h"

#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>

namespace phalanx::host::record {

std::string CsvRecorder::open(const std::string& path, const protocol::DeviceLayout& layout, bool sync_column) {
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd_ < 0) return "cannot write recording " + path + ": " + std::strerror(errno);
  path_ = path;
  sync_column_ = sync_column;
  samples_ = layout.sample_count;
  setpoints_ = layout.setpoint_count;
  std::string header = "t_s,device_time_us,seq,cmd_seq_echo,mode,fault_bits";
  for (uint8_t i = 0; i < layout.sample_count; ++i) header += ",sample" + std::to_string(i);
  for (uint8_t i = 0; i < layout.setpoint_count; ++i) header += ",setpoint" + std::to_string(i);
  // Rising edges of the sync pulse emitted so far: the motion-capture frame index (docs/gpio.md).
  if (sync_column) header += ",sync_pulses";
  header += "\n";
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

void CsvRecorder::row(double t_s, const TelemetryFrame& tel, const protocol::Command& cmd, uint64_t sync_pulses) {
  if (!queue_) return;
  if (failed()) {
    countLost(1);
    return;
  }
  Row r;
  r.t_s = t_s;
  r.device_time_us = tel.device_time_us;
  r.sync_pulses = sync_pulses;
  r.seq = tel.seq;
  r.cmd_seq_echo = tel.cmd_seq_echo;
  r.fault_bits = tel.fault_bits;
  r.mode = static_cast<uint8_t>(tel.mode);
  std::copy(tel.value.begin(), tel.value.begin() + samples_, r.sample.begin());
  std::copy(cmd.setpoint, cmd.setpoint + setpoints_, r.setpoint.begin());
  if (!queue_->push(r)) countLost(1);
}

void CsvRecorder::close() {
  if (writer_.joinable()) {
    running_ = false;
    writer_.join();
  }
  queue_.reset();
  if (fd_ < 0) return;
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
      format(r);
      ++n;
      if (pending_rows_ >= kRowsPerWrite) writePending();
    }
    if (!more) break;
    if (n == 0) usleep(5000);
  }
  writePending();
}

void CsvRecorder::writePending() {
  if (pending_rows_ == 0) return;
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

void CsvRecorder::format(const Row& r) {
  char buf[64];
  auto put = [&](int n) { pending_.append(buf, static_cast<std::size_t>(std::min<int>(n, sizeof buf - 1))); };
  put(std::snprintf(buf, sizeof buf, "%.6f,%llu,%u,%u,%u,%u", r.t_s, static_cast<unsigned long long>(r.device_time_us),
                    r.seq, r.cmd_seq_echo, static_cast<unsigned>(r.mode), r.fault_bits));
  for (uint8_t i = 0; i < samples_; ++i) put(std::snprintf(buf, sizeof buf, ",%.5g", static_cast<double>(r.sample[i])));
  for (uint8_t i = 0; i < setpoints_; ++i) put(std::snprintf(buf, sizeof buf, ",%.5g", static_cast<double>(r.setpoint[i])));
  if (sync_column_) put(std::snprintf(buf, sizeof buf, ",%llu", static_cast<unsigned long long>(r.sync_pulses)));
  pending_.push_back('\n');
  ++pending_rows_;
}

}  // namespace phalanx::host::record
