#include "phalanx/host/record/csv_recorder.h"

#include <pthread.h>
#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace phalanx::host::record {

std::string CsvRecorder::open(const std::string& path, const protocol::DeviceLayout& layout, bool sync_column) {
  f_ = std::fopen(path.c_str(), "w");
  if (f_ == nullptr) return "cannot write recording " + path + ": " + std::strerror(errno);
  std::setvbuf(f_, nullptr, _IOFBF, 1 << 20);
  std::fprintf(f_, "t_s,device_time_us,seq,cmd_seq_echo,mode,fault_bits");
  for (uint8_t i = 0; i < layout.sample_count; ++i) std::fprintf(f_, ",sample%u", i);
  for (uint8_t i = 0; i < layout.setpoint_count; ++i) std::fprintf(f_, ",setpoint%u", i);
  // Rising edges of the sync pulse emitted so far: the motion-capture frame index (docs/gpio.md).
  if (sync_column) std::fprintf(f_, ",sync_pulses");
  std::fprintf(f_, "\n");
  sync_column_ = sync_column;
  samples_ = layout.sample_count;
  setpoints_ = layout.setpoint_count;
  // Allocated and touched here, before the loop (and before mlockall, which then locks it).
  queue_ = std::make_unique<SpscQueue<Row>>(kQueueRows);
  running_ = true;
  writer_ = std::thread([this] { writerMain(); });
  return {};
}

void CsvRecorder::row(double t_s, const TelemetryFrame& tel, const protocol::Command& cmd, uint64_t sync_pulses) {
  if (!queue_) return;
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
  if (queue_->push(r)) {
    ++rows_;
  } else {
    ++dropped_;
  }
}

void CsvRecorder::close() {
  if (writer_.joinable()) {
    running_ = false;
    writer_.join();
  }
  queue_.reset();
  if (f_ != nullptr) std::fclose(f_);
  f_ = nullptr;
}

void CsvRecorder::writerMain() {
  // Created before the loop goes SCHED_FIFO; made explicit anyway: the writer must never compete with the loop.
  sched_param normal{};
  normal.sched_priority = 0;
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);
  Row r;
  uint64_t since_flush = 0;
  for (;;) {
    const bool more = running_.load();
    size_t n = 0;
    while (queue_->pop(r)) {
      format(r);
      ++n;
    }
    since_flush += n;
    if (!more) break;
    // Hand the rows to the kernel about every 100 ms of recording (a crash loses at most that much).
    if (since_flush >= 100) {
      std::fflush(f_);
      since_flush = 0;
    }
    if (n == 0) usleep(5000);
  }
  std::fflush(f_);
}

void CsvRecorder::format(const Row& r) {
  std::fprintf(f_, "%.6f,%llu,%u,%u,%u,%u", r.t_s, static_cast<unsigned long long>(r.device_time_us), r.seq,
               r.cmd_seq_echo, static_cast<unsigned>(r.mode), r.fault_bits);
  for (uint8_t i = 0; i < samples_; ++i) std::fprintf(f_, ",%.5g", static_cast<double>(r.sample[i]));
  for (uint8_t i = 0; i < setpoints_; ++i) std::fprintf(f_, ",%.5g", static_cast<double>(r.setpoint[i]));
  if (sync_column_) std::fprintf(f_, ",%llu", static_cast<unsigned long long>(r.sync_pulses));
  std::fputc('\n', f_);
}

}  // namespace phalanx::host::record
