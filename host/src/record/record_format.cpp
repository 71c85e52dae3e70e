#include "phalanx/host/record/record_format.h"

#include <zlib.h>

#include <cstring>

namespace phalanx::host::record {
namespace {

// Explicit little-endian encoding, independent of the host's byte order.
template <class U>
void putLe(uint8_t*& p, U v) {
  for (std::size_t i = 0; i < sizeof(U); ++i) *p++ = static_cast<uint8_t>(static_cast<uint64_t>(v) >> (8 * i));
}
template <class U>
U getLe(const uint8_t*& p) {
  uint64_t v = 0;
  for (std::size_t i = 0; i < sizeof(U); ++i) v |= static_cast<uint64_t>(*p++) << (8 * i);
  return static_cast<U>(v);
}
void putF32(uint8_t*& p, float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  putLe(p, u);
}
float getF32(const uint8_t*& p) {
  const uint32_t u = getLe<uint32_t>(p);
  float f;
  std::memcpy(&f, &u, 4);
  return f;
}
void putF64(uint8_t*& p, double d) {
  uint64_t u;
  std::memcpy(&u, &d, 8);
  putLe(p, u);
}
double getF64(const uint8_t*& p) {
  const uint64_t u = getLe<uint64_t>(p);
  double d;
  std::memcpy(&d, &u, 8);
  return d;
}

}  // namespace

void appendRecord(std::vector<uint8_t>& out, RecordType type, const uint8_t* payload, std::size_t length) {
  if (length > kMaxPayload) length = kMaxPayload;  // callers keep payloads small; never write a bad length
  const std::size_t start = out.size();
  out.resize(start + kRecordOverhead + length);
  uint8_t* p = out.data() + start;
  putLe<uint32_t>(p, kSync);
  uint8_t* crc_start = p;
  putLe<uint16_t>(p, static_cast<uint16_t>(length));
  *p++ = static_cast<uint8_t>(type);
  *p++ = 0;
  if (length > 0) std::memcpy(p, payload, length);
  p += length;
  const uLong crc = crc32(0L, crc_start, static_cast<uInt>(4 + length));
  putLe<uint32_t>(p, static_cast<uint32_t>(crc));
}

std::size_t encodeCycle(const CycleRecord& c, uint8_t* out) {
  uint8_t* p = out;
  putLe<uint64_t>(p, c.host_ns);
  putF64(p, c.t_s);
  putLe<uint64_t>(p, c.device_time_us);
  putLe<uint16_t>(p, c.tel_seq);
  putLe<uint16_t>(p, c.cmd_seq_echo);
  putLe<uint16_t>(p, c.cmd_seq);
  putLe<uint16_t>(p, c.fault_bits);
  *p++ = c.tel_mode;
  *p++ = c.cmd_mode;
  *p++ = c.state_flags;
  const uint8_t ns = c.sample_count <= protocol::kMaxSamples ? c.sample_count : protocol::kMaxSamples;
  const uint8_t nc = c.setpoint_count <= protocol::kMaxSetpoints ? c.setpoint_count : protocol::kMaxSetpoints;
  const uint8_t na = c.aux_count <= kMaxAux ? c.aux_count : kMaxAux;
  *p++ = ns;
  *p++ = nc;
  *p++ = na;
  for (uint8_t i = 0; i < ns; ++i) putF32(p, c.sample[i]);
  for (uint8_t i = 0; i < nc; ++i) putF32(p, c.setpoint[i]);
  for (uint8_t i = 0; i < na; ++i) putF32(p, c.aux[i]);
  return static_cast<std::size_t>(p - out);
}

bool decodeCycle(const uint8_t* payload, std::size_t length, CycleRecord& c) {
  constexpr std::size_t kFixed = 8 + 8 + 8 + 8 + 6;
  if (length < kFixed) return false;
  const uint8_t* p = payload;
  c.host_ns = getLe<uint64_t>(p);
  c.t_s = getF64(p);
  c.device_time_us = getLe<uint64_t>(p);
  c.tel_seq = getLe<uint16_t>(p);
  c.cmd_seq_echo = getLe<uint16_t>(p);
  c.cmd_seq = getLe<uint16_t>(p);
  c.fault_bits = getLe<uint16_t>(p);
  c.tel_mode = *p++;
  c.cmd_mode = *p++;
  c.state_flags = *p++;
  c.sample_count = *p++;
  c.setpoint_count = *p++;
  c.aux_count = *p++;
  if (c.sample_count > protocol::kMaxSamples || c.setpoint_count > protocol::kMaxSetpoints || c.aux_count > kMaxAux) {
    return false;
  }
  if (length != kFixed + 4u * (c.sample_count + c.setpoint_count + c.aux_count)) return false;
  for (uint8_t i = 0; i < c.sample_count; ++i) c.sample[i] = getF32(p);
  for (uint8_t i = 0; i < c.setpoint_count; ++i) c.setpoint[i] = getF32(p);
  for (uint8_t i = 0; i < c.aux_count; ++i) c.aux[i] = getF32(p);
  return true;
}

std::vector<uint8_t> encodeCycleBlock(const uint8_t* cycles, uint16_t count, uint16_t length) {
  const std::size_t n = static_cast<std::size_t>(count) * length;
  std::vector<uint8_t> shuffled(n);
  for (std::size_t i = 0; i < count; ++i) {
    for (std::size_t k = 0; k < length; ++k) shuffled[k * count + i] = cycles[i * length + k];
  }
  uLongf out_len = compressBound(static_cast<uLong>(n));
  std::vector<uint8_t> out(4 + out_len);
  if (compress2(out.data() + 4, &out_len, shuffled.data(), static_cast<uLong>(n), 6) != Z_OK ||
      4 + out_len > kMaxPayload) {
    return {};
  }
  out.resize(4 + out_len);
  uint8_t* p = out.data();
  putLe<uint16_t>(p, count);
  putLe<uint16_t>(p, length);
  return out;
}

bool decodeCycleBlock(const uint8_t* payload, std::size_t length, std::vector<CycleRecord>& out) {
  if (length < 4) return false;
  const uint8_t* p = payload;
  const uint16_t count = getLe<uint16_t>(p);
  const uint16_t len = getLe<uint16_t>(p);
  const std::size_t n = static_cast<std::size_t>(count) * len;
  if (n == 0 || n > kMaxBlockBytes + kMaxCyclePayload) return false;
  std::vector<uint8_t> shuffled(n);
  uLongf got = static_cast<uLongf>(n);
  if (uncompress(shuffled.data(), &got, p, static_cast<uLong>(length - 4)) != Z_OK || got != n) return false;
  std::vector<uint8_t> cycle(len);
  const std::size_t before = out.size();
  for (std::size_t i = 0; i < count; ++i) {
    for (std::size_t k = 0; k < len; ++k) cycle[k] = shuffled[k * count + i];
    CycleRecord c;
    if (!decodeCycle(cycle.data(), len, c)) {
      out.resize(before);
      return false;
    }
    out.push_back(c);
  }
  return true;
}

}  // namespace phalanx::host::record
