#include "phalanx/host/record/record_writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>

namespace phalanx::host::record {

RecordWriter::RecordWriter(const WriterConfig& config) : config_(config), queue_(config.queue_cycles) {
  buffer_.reserve(1 << 20);
  block_.reserve(kMaxBlockBytes + kMaxCyclePayload);
  record_ends_.reserve(config.queue_cycles + 512);
  cycle_ends_.reserve(config.queue_cycles);
}

RecordWriter::~RecordWriter() {
  if (started_) close();
  else discard();
}

std::string RecordWriter::create(const std::string& path, int* err_no) {
  if (err_no != nullptr) *err_no = 0;
  if (fd_ >= 0) return "recorder already open on " + path_;
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0640);
  if (fd_ < 0) {
    if (err_no != nullptr) *err_no = errno;
    return "cannot create session record " + path + ": " + std::strerror(errno);
  }
  path_ = path;
  return {};
}

std::string RecordWriter::start(const nlohmann::json& header) {
  if (fd_ < 0) return "session record: start without create";
  if (started_) return "session record " + path_ + ": already started";
  buffer_.assign(kFileMagic, kFileMagic + sizeof kFileMagic);
  record_ends_.assign(1, buffer_.size());
  cycle_ends_.clear();
  const std::string text = header.dump();
  add(RecordType::kHeader, reinterpret_cast<const uint8_t*>(text.data()), text.size());
  writeBuffer();
  if (failed()) return error();
  if (const int e = syncData(fd_); e != 0) {
    fail("session record " + path_ + ": fdatasync failed: " + std::strerror(e));
    return error();
  }
  started_ = true;
  stop_ = false;
  thread_ = std::thread([this] { run(); });
  return {};
}

std::string RecordWriter::open(const std::string& path, const nlohmann::json& header) {
  if (std::string err = create(path); !err.empty()) return err;
  return start(header);
}

void RecordWriter::discard() {
  if (fd_ < 0 || started_) return;
  ::close(fd_);
  fd_ = -1;
  ::unlink(path_.c_str());
}

bool RecordWriter::pushCycle(const CycleRecord& cycle) {
  if (queue_.push(cycle)) return true;
  dropped_.fetch_add(1, std::memory_order_relaxed);
  return false;
}

bool RecordWriter::pushLoopEvent(const LoopEvent& event) {
  if (loop_events_.push(event)) return true;
  loop_events_dropped_.fetch_add(1, std::memory_order_relaxed);
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

void RecordWriter::add(RecordType type, const uint8_t* payload, std::size_t length, std::size_t cycles) {
  appendRecord(buffer_, type, payload, length);
  record_ends_.push_back(buffer_.size());
  cycle_ends_.insert(cycle_ends_.end(), cycles, buffer_.size());
}

void RecordWriter::addBlock() {
  if (block_count_ == 0) return;
  const std::vector<uint8_t> b = encodeCycleBlock(block_.data(), block_count_, block_length_);
  if (!b.empty()) {
    add(RecordType::kCycleBlock, b.data(), b.size(), block_count_);
  } else {
    for (uint16_t i = 0; i < block_count_; ++i) {
      add(RecordType::kCycle, block_.data() + static_cast<std::size_t>(i) * block_length_, block_length_, 1);
    }
  }
  block_.clear();
  block_count_ = 0;
}

void RecordWriter::fail(const std::string& what) { failure_.set(what); }

void RecordWriter::writeBuffer() {
  const uint64_t cycles = cycle_ends_.size();
  if (failed()) {
    cycles_unwritten_.fetch_add(cycles);
    return;
  }
  int err_no = 0;
  const std::size_t done = writeFully(fd_, buffer_.data(), buffer_.size(), err_no);
  // A cycle counts as written only when all of its bytes reached the file.
  const auto whole = static_cast<uint64_t>(std::upper_bound(cycle_ends_.begin(), cycle_ends_.end(), done) -
                                           cycle_ends_.begin());
  cycles_written_.fetch_add(whole);
  cycles_unwritten_.fetch_add(cycles - whole);
  if (err_no == 0) {
    file_bytes_ += done;
    return;
  }
  // Cut the file back to its last whole record, so it ends cleanly where the recording stopped.
  const auto last = std::upper_bound(record_ends_.begin(), record_ends_.end(), done);
  const std::size_t keep = last == record_ends_.begin() ? 0 : *(last - 1);
  if (::ftruncate(fd_, static_cast<off_t>(file_bytes_ + keep)) == 0) file_bytes_ += keep;
  fail("session record " + path_ + ": writing failed: " + std::strerror(err_no) + " (" +
       std::to_string(cycles_written_.load()) + " cycles written; nothing after them is recorded)");
}

bool RecordWriter::drainOnce() {
  buffer_.clear();
  record_ends_.clear();
  cycle_ends_.clear();
  CycleRecord c;
  uint8_t payload[kMaxCyclePayload];
  while (queue_.pop(c)) {
    const std::size_t n = encodeCycle(c, payload);
    if (!config_.cycle_blocks) {
      add(RecordType::kCycle, payload, n, 1);
      continue;
    }
    if (block_count_ > 0 && (n != block_length_ || block_.size() + n > kMaxBlockBytes)) addBlock();
    block_length_ = static_cast<uint16_t>(n);
    block_.insert(block_.end(), payload, payload + n);
    ++block_count_;
  }
  addBlock();
  LoopEvent le;
  while (loop_events_.pop(le)) {
    const std::string text = loopEventJson(le).dump();
    add(RecordType::kEvent, reinterpret_cast<const uint8_t*>(text.data()), text.size());
  }
  std::vector<std::vector<uint8_t>> events;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    events.swap(events_);
  }
  for (const auto& e : events) {
    buffer_.insert(buffer_.end(), e.begin(), e.end());
    record_ends_.push_back(buffer_.size());
  }
  const uint64_t dropped = dropped_.load(std::memory_order_relaxed);
  if (dropped != dropped_reported_) {
    const std::string text =
        nlohmann::json{{"t_s", c.t_s}, {"kind", "record-gap"}, {"cycles_dropped_total", dropped}}.dump();
    add(RecordType::kEvent, reinterpret_cast<const uint8_t*>(text.data()), text.size());
    dropped_reported_ = dropped;
  }
  if (buffer_.empty()) return false;
  writeBuffer();
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
    if (clock::now() >= next_sync && !failed()) {
      if (const int e = syncData(fd_); e != 0) fail("session record " + path_ + ": fdatasync failed: " + std::strerror(e));
      next_sync = clock::now() + std::chrono::milliseconds(config_.sync_period_ms);
    }
  }
}

void RecordWriter::close(const nlohmann::json& footer) {
  if (fd_ < 0) return;
  if (!started_) {
    discard();
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  drainOnce();
  if (!footer.is_null() && !failed()) {
    nlohmann::json f = footer;
    f["cycles_written"] = cycles_written_.load();
    f["cycles_dropped"] = dropped_.load();
    f["cycles_lost"] = cyclesLost();
    f["loop_events_dropped"] = loop_events_dropped_.load();
    const std::string text = f.dump();
    buffer_.clear();
    record_ends_.clear();
    cycle_ends_.clear();
    add(RecordType::kFooter, reinterpret_cast<const uint8_t*>(text.data()), text.size());
    writeBuffer();
  }
  if (!failed()) {
    if (const int e = syncData(fd_); e != 0) fail("session record " + path_ + ": fdatasync failed: " + std::strerror(e));
  }
  if (::close(fd_) != 0 && !failed()) fail("session record " + path_ + ": close failed: " + std::strerror(errno));
  fd_ = -1;
  started_ = false;
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
    case LoopEvent::Kind::kPlanStepEnded:
      j["kind"] = "plan-step-ended";
      j["step"] = e.code;
      j["ended_by"] = e.detail == 2 ? "repetitions" : "duration";
      j["counted_s"] = e.value;
      j["repetitions"] = e.count;
      break;
  }
  return j;
}
}  // namespace

}  // namespace phalanx::host::record
