#include "phalanx/host/record/record_writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>

namespace phalanx::host::record {

RecordWriter::RecordWriter(const WriterConfig& config) : config_(config), queue_(config.queue_cycles) {
  buffer_.reserve(1 << 20);
}

RecordWriter::~RecordWriter() { close(); }

std::string RecordWriter::open(const std::string& path, const nlohmann::json& header) {
  if (fd_ >= 0) return "recorder already open on " + path_;
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0640);
  if (fd_ < 0) return "cannot create session record " + path + ": " + std::strerror(errno);
  path_ = path;
  std::vector<uint8_t> bytes(kFileMagic, kFileMagic + sizeof kFileMagic);
  const std::string text = header.dump();
  appendRecord(bytes, RecordType::kHeader, reinterpret_cast<const uint8_t*>(text.data()), text.size());
  writeBytes(bytes);
  if (::fdatasync(fd_) != 0 && error_.empty()) error_ = std::string("fdatasync: ") + std::strerror(errno);
  stop_ = false;
  thread_ = std::thread([this] { run(); });
  return {};
}

bool RecordWriter::pushCycle(const CycleRecord& cycle) {
  if (queue_.push(cycle)) return true;
  dropped_.fetch_add(1, std::memory_order_relaxed);
  return false;
}

bool RecordWriter::pushLoopEvent(const LoopEvent& event) {
  if (loop_events_.push(event)) return true;
  dropped_.fetch_add(1, std::memory_order_relaxed);
  return false;
}

namespace {
nlohmann::json loopEventJson(const LoopEvent& e);
}

void RecordWriter::pushEvent(double t_s, const std::string& kind, nlohmann::json fields) {
  if (!fields.is_object()) fields = nlohmann::json{{"value", fields}};
  fields["t_s"] = t_s;
  fields["kind"] = kind;
  const std::string text = fields.dump();
  std::vector<uint8_t> rec;
  appendRecord(rec, RecordType::kEvent, reinterpret_cast<const uint8_t*>(text.data()), text.size());
  std::lock_guard<std::mutex> lock(mutex_);
  events_.push_back(std::move(rec));
}

std::string RecordWriter::error() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return error_;
}

void RecordWriter::writeBytes(const std::vector<uint8_t>& bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (error_.empty()) error_ = "writing " + path_ + ": " + std::strerror(errno);
      return;
    }
    done += static_cast<std::size_t>(n);
  }
}

bool RecordWriter::drainOnce() {
  buffer_.clear();
  CycleRecord c;
  uint8_t payload[kMaxCyclePayload];
  uint64_t n = 0;
  while (queue_.pop(c)) {
    appendRecord(buffer_, RecordType::kCycle, payload, encodeCycle(c, payload));
    ++n;
  }
  LoopEvent le;
  while (loop_events_.pop(le)) {
    const std::string text = loopEventJson(le).dump();
    appendRecord(buffer_, RecordType::kEvent, reinterpret_cast<const uint8_t*>(text.data()), text.size());
  }
  std::vector<std::vector<uint8_t>> events;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    events.swap(events_);
  }
  for (const auto& e : events) buffer_.insert(buffer_.end(), e.begin(), e.end());
  const uint64_t dropped = dropped_.load(std::memory_order_relaxed);
  if (dropped != dropped_reported_) {
    const std::string text =
        nlohmann::json{{"t_s", c.t_s}, {"kind", "record-gap"}, {"cycles_dropped_total", dropped}}.dump();
    appendRecord(buffer_, RecordType::kEvent, reinterpret_cast<const uint8_t*>(text.data()), text.size());
    dropped_reported_ = dropped;
  }
  if (buffer_.empty()) return false;
  writeBytes(buffer_);
  cycles_written_.fetch_add(n, std::memory_order_relaxed);
  return true;
}

void RecordWriter::run() {
  using clock = std::chrono::steady_clock;
  auto next_sync = clock::now() + std::chrono::milliseconds(config_.sync_period_ms);
  while (!stop_.load()) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait_for(lock, std::chrono::milliseconds(config_.flush_period_ms), [this] { return stop_.load(); });
    }
    drainOnce();
    if (clock::now() >= next_sync) {
      ::fdatasync(fd_);
      next_sync = clock::now() + std::chrono::milliseconds(config_.sync_period_ms);
    }
  }
}

void RecordWriter::close(const nlohmann::json& footer) {
  if (fd_ < 0) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  drainOnce();
  if (!footer.is_null()) {
    std::vector<uint8_t> rec;
    nlohmann::json f = footer;
    f["cycles_written"] = cycles_written_.load();
    f["cycles_dropped"] = dropped_.load();
    const std::string text = f.dump();
    appendRecord(rec, RecordType::kFooter, reinterpret_cast<const uint8_t*>(text.data()), text.size());
    writeBytes(rec);
  }
  ::fdatasync(fd_);
  ::close(fd_);
  fd_ = -1;
}

namespace {
nlohmann::json loopEventJson(const LoopEvent& e) {
  nlohmann::json j{{"t_s", e.t_s}};
  switch (e.kind) {
    case LoopEvent::Kind::kDeviceEvent:
      j["kind"] = "device-event";
      j["code"] = e.code;
      j["channel"] = e.channel;
      j["detail"] = e.detail;
      j["value"] = e.value;
      break;
    case LoopEvent::Kind::kExerciseStarted:
      j["kind"] = "exercise-started";
      j["exercise_id"] = e.code;
      break;
    case LoopEvent::Kind::kLimitActive:
      j["kind"] = "limit-active";
      j["channels"] = e.code;
      break;
    case LoopEvent::Kind::kFaultBits:
      j["kind"] = "fault-bits";
      j["bits"] = e.code;
      break;
  }
  return j;
}
}  // namespace

}  // namespace phalanx::host::record
