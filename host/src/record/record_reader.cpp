#include "phalanx/host/record/record_reader.h"

#include "phalanx/host/therapy/device.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <memory>
#include <cstdio>
#include <cstring>
#include <new>

namespace phalanx::host::record {
namespace {

uint32_t le32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | static_cast<uint32_t>(p[1]) << 8 | static_cast<uint32_t>(p[2]) << 16 |
         static_cast<uint32_t>(p[3]) << 24;
}

nlohmann::json parseJson(const uint8_t* p, std::size_t n) {
  return nlohmann::json::parse(p, p + n, nullptr, /*allow_exceptions=*/false);
}

}  // namespace

therapy::KinematicParams kinematicsFromHeader(const nlohmann::json& h) {
  therapy::KinematicParams k;
  if (!h.is_object() || !h.contains("kinematics") || !h["kinematics"].is_object()) return k;
  for (const auto& [ch, v] : h["kinematics"].items()) {
    if (!v.is_object()) continue;
    k.segment_lengths_mm.emplace_back(ch, std::array<double, 3>{v.value("p1_mm", 0.0), v.value("p2_mm", 0.0),
                                                                v.value("p3_mm", 0.0)});
  }
  return k;
}

int SessionRecord::auxIndex(const std::string& name) const {
  if (!header.is_object() || !header.contains("aux") || !header["aux"].is_array()) return -1;
  for (std::size_t i = 0; i < header["aux"].size(); ++i) {
    if (header["aux"][i].is_string() && header["aux"][i].get<std::string>() == name) return static_cast<int>(i);
  }
  return -1;
}

namespace {

const char* fileKind(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

/// The whole regular file, at most the size fstat gave (a file growing meanwhile is read up to that size).
std::string readRegularFile(const std::string& path, std::vector<uint8_t>& data, FileId& id) {
  // O_NONBLOCK: opening a FIFO must not wait for a writer; it is refused below anyway.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) return "cannot read " + path + ": " + std::strerror(errno);
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    const std::string kind = fileKind(st.st_mode);
    ::close(fd);
    return "not a record: " + path + " is " + kind + (kind == "not a regular file" ? "" : ", not a regular file");
  }
  id = {st.st_dev, st.st_ino, true};
  try {
    data.resize(static_cast<std::size_t>(st.st_size));
  } catch (const std::bad_alloc&) {
    ::close(fd);
    return "cannot read " + path + ": " + std::to_string(st.st_size) + " bytes do not fit in memory";
  }
  std::size_t got = 0;
  while (got < data.size()) {
    const ssize_t n = ::read(fd, data.data() + got, data.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int e = errno;
      ::close(fd);
      return "cannot read " + path + ": " + std::strerror(e);
    }
    if (n == 0) break;  // shrank meanwhile
    got += static_cast<std::size_t>(n);
  }
  ::close(fd);
  data.resize(got);
  return {};
}

}  // namespace

std::string readRecord(const std::string& path, SessionRecord& out,
                       const std::function<void(uint64_t, uint64_t)>& progress) {
  out = SessionRecord{};
  std::vector<uint8_t> data;
  FileId id;
  if (std::string err = readRegularFile(path, data, id); !err.empty()) return err;
  const std::string err = parseRecord(data, out, progress);
  out.source = path;
  out.source_id = id;
  return err.empty() ? err : path + ": " + err;
}

std::string parseRecord(const std::vector<uint8_t>& data, SessionRecord& out,
                        const std::function<void(uint64_t, uint64_t)>& progress) {
  out = SessionRecord{};
  out.bytes_total = data.size();
  if (data.size() < sizeof kFileMagic || std::memcmp(data.data(), kFileMagic, sizeof kFileMagic) != 0) {
    return "not a Phalanx session record (bad magic)";
  }
  std::size_t pos = sizeof kFileMagic;
  uint64_t next_progress = 0;
  bool in_bad_run = false;
  auto skipByte = [&] {
    ++out.bytes_skipped;
    if (!in_bad_run) ++out.bad_records;
    in_bad_run = true;
    ++pos;
  };
  while (pos < data.size()) {
    if (progress && pos >= next_progress) {
      progress(pos, data.size());
      next_progress = pos + (8u << 20);
    }
    const std::size_t left = data.size() - pos;
    if (left < 4) {
      // The start of a sync word at the very end: the writer stopped inside it.
      uint8_t sync[4];
      for (int i = 0; i < 4; ++i) sync[i] = static_cast<uint8_t>(kSync >> (8 * i));
      if (std::memcmp(&data[pos], sync, left) == 0) {
        out.torn_tail = true;
        break;
      }
      skipByte();
      continue;
    }
    if (le32(&data[pos]) != kSync) {
      skipByte();
      continue;
    }
    if (left < kRecordOverhead) {
      out.torn_tail = true;
      break;
    }
    const std::size_t len = static_cast<std::size_t>(data[pos + 4]) | static_cast<std::size_t>(data[pos + 5]) << 8;
    if (left < kRecordOverhead + len) {
      out.torn_tail = true;  // the last record was being written when the writer stopped
      break;
    }
    const uint8_t* body = &data[pos + 4];
    const uint32_t crc = le32(body + 4 + len);
    if (static_cast<uint32_t>(crc32(0L, body, static_cast<uInt>(4 + len))) != crc) {
      skipByte();
      continue;
    }
    in_bad_run = false;
    const auto type = static_cast<RecordType>(body[2]);
    const uint8_t* payload = body + 4;
    switch (type) {
      case RecordType::kHeader: out.header = parseJson(payload, len); break;
      case RecordType::kCycle: {
        CycleRecord c;
        if (decodeCycle(payload, len, c)) out.cycles.push_back(c);
        else ++out.bad_records;
        break;
      }
      case RecordType::kCycleBlock:
        if (!decodeCycleBlock(payload, len, out.cycles)) ++out.bad_records;
        break;
      case RecordType::kEvent: {
        nlohmann::json e = parseJson(payload, len);
        if (!e.is_discarded()) out.events.push_back(std::move(e));
        break;
      }
      case RecordType::kFooter: out.footer = parseJson(payload, len); break;
      default: ++out.bad_records; break;  // a newer record type: skipped, counted
    }
    pos += kRecordOverhead + len;
  }
  if (out.torn_tail) out.bytes_skipped += data.size() - pos;
  if (out.header.is_discarded()) out.header = nullptr;
  if (out.footer.is_discarded()) out.footer = nullptr;
  if (progress) progress(data.size(), data.size());
  return {};
}

std::string exportCsv(const SessionRecord& rec, const std::string& csv_path,
                      const std::function<void(uint64_t, uint64_t)>& progress) {
  if (rec.source_id == fileId(csv_path)) {
    return "refusing to write " + csv_path + ": it is the record being exported (" + rec.source + ", the same file)";
  }
  AtomicOutputFile f;
  if (std::string err = f.open(csv_path); !err.empty()) return err;
  auto names = [&](const char* key, const char* prefix, std::size_t n) {
    std::vector<std::string> v;
    for (std::size_t i = 0; i < n; ++i) {
      std::string name = std::string(prefix) + std::to_string(i);
      if (rec.header.is_object() && rec.header.contains(key) && rec.header[key].is_array() &&
          i < rec.header[key].size() && rec.header[key][i].is_string()) {
        name = rec.header[key][i].get<std::string>();
      }
      v.push_back(name);
    }
    return v;
  };
  const std::size_t ns = rec.cycles.empty() ? 0 : rec.cycles.front().sample_count;
  const std::size_t nc = rec.cycles.empty() ? 0 : rec.cycles.front().setpoint_count;
  const std::size_t na = rec.cycles.empty() ? 0 : rec.cycles.front().aux_count;
  std::string line = "t_s,host_ns,device_time_us,tel_seq,cmd_seq_echo,cmd_seq,tel_mode,cmd_mode,fault_bits,state_flags";
  for (const auto& n : names("samples", "sample", ns)) line += "," + n;
  for (const auto& n : names("setpoints", "setpoint", nc)) line += "," + n;
  for (const auto& n : names("aux", "aux", na)) line += "," + n;
  // Joint flexion in degrees (flexion positive), through the device's kinematics with the patient's parameters
  // from the header, as the report computes it: every report figure can be recomputed from the export.
  std::string dev_err;
  std::unique_ptr<therapy::TherapyDevice> dev;
  if (rec.header.is_object() && rec.header.contains("device") && rec.header["device"].is_string()) {
    dev = therapy::makeTherapyDevice(rec.header["device"].get<std::string>(), kinematicsFromHeader(rec.header), dev_err);
  }
  const std::size_t nj = dev ? dev->jointCount() : 0;
  for (std::size_t j = 0; j < nj; ++j) line += "," + dev->jointName(j) + "_flexion_deg";
  line += "\n";
  f.write(line);
  char buf[160];
  auto put = [&](int n) { f.write(buf, static_cast<std::size_t>(std::min<int>(n, sizeof buf - 1))); };
  auto value = [&](uint8_t count, std::size_t k, float v) {
    // 9 significant digits: a float32 round-trips exactly.
    put(std::snprintf(buf, sizeof buf, ",%.9g", k < count ? static_cast<double>(v) : 0.0));
  };
  uint64_t i = 0;
  for (const CycleRecord& c : rec.cycles) {
    if (progress && (i % 100000) == 0) progress(i, rec.cycles.size());
    ++i;
    put(std::snprintf(buf, sizeof buf, "%.6f,%llu,%llu,%u,%u,%u,%u,%u,%u,%u", c.t_s,
                      static_cast<unsigned long long>(c.host_ns), static_cast<unsigned long long>(c.device_time_us),
                      c.tel_seq, c.cmd_seq_echo, c.cmd_seq, c.tel_mode, c.cmd_mode, c.fault_bits, c.state_flags));
    // Rows keep the first cycle's column count (a session's layout never changes).
    // (decodeCycle keeps every count within its array.)
    for (std::size_t k = 0; k < ns; ++k) value(c.sample_count, k, c.sample[k]);
    for (std::size_t k = 0; k < nc; ++k) value(c.setpoint_count, k, c.setpoint[k]);
    for (std::size_t k = 0; k < na; ++k) value(c.aux_count, k, c.aux[k]);
    if (nj > 0) {
      TelemetryFrame tel;
      tel.device_time_us = c.device_time_us;
      tel.mode = static_cast<protocol::Mode>(c.tel_mode);
      tel.fault_bits = c.fault_bits;
      tel.sample_count = c.sample_count;
      for (std::size_t k = 0; k < c.sample_count; ++k) tel.value[k] = c.sample[k];
      therapy::Observation obs{};
      dev->observe(tel, obs);
      for (std::size_t j = 0; j < nj; ++j) {
        // Empty when the kinematics give no measurement of the joint (the report skips those cycles too).
        if (obs.joint_valid[j]) put(std::snprintf(buf, sizeof buf, ",%.17g", obs.flexion_rad[j] * (180.0 / M_PI)));
        else f.write(",", 1);
      }
    }
    if (!f.write("\n", 1)) break;
  }
  if (progress) progress(rec.cycles.size(), rec.cycles.size());
  return f.commit();
}

}  // namespace phalanx::host::record
