#include "phalanx/host/record/mcap_writer.h"

#include <zlib.h>
#include <zstd.h>

#include <algorithm>

namespace phalanx::host::record {
namespace {

constexpr uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
enum Op : uint8_t {
  kHeader = 0x01, kFooter = 0x02, kSchema = 0x03, kChannel = 0x04, kMessage = 0x05, kChunk = 0x06,
  kMessageIndex = 0x07, kChunkIndex = 0x08, kStatistics = 0x0B, kMetadata = 0x0C, kMetadataIndex = 0x0D, kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

// Little-endian serialisation of the spec's types (section "Serialization").
struct Out {
  std::vector<uint8_t>& b;
  void u8(uint8_t v) { b.push_back(v); }
  template <class U>
  void le(U v) {
    for (std::size_t i = 0; i < sizeof(U); ++i) b.push_back(static_cast<uint8_t>(static_cast<uint64_t>(v) >> (8 * i)));
  }
  void u16(uint16_t v) { le(v); }
  void u32(uint32_t v) { le(v); }
  void u64(uint64_t v) { le(v); }
  void raw(const void* p, std::size_t n) {
    const auto* c = static_cast<const uint8_t*>(p);
    b.insert(b.end(), c, c + n);
  }
  void str(const std::string& s) {
    u32(static_cast<uint32_t>(s.size()));
    raw(s.data(), s.size());
  }
  void strMap(const std::map<std::string, std::string>& m) {
    std::vector<uint8_t> body;
    Out o{body};
    for (const auto& [k, v] : m) {
      o.str(k);
      o.str(v);
    }
    u32(static_cast<uint32_t>(body.size()));
    raw(body.data(), body.size());
  }
  /// Opcode and a length placeholder; returns the position to patch with endRecord().
  std::size_t beginRecord(uint8_t op) {
    u8(op);
    const std::size_t at = b.size();
    u64(0);
    return at;
  }
  void endRecord(std::size_t at) {
    const uint64_t len = b.size() - at - 8;
    for (std::size_t i = 0; i < 8; ++i) b[at + i] = static_cast<uint8_t>(len >> (8 * i));
  }
};

}  // namespace

uint32_t mcapCrc(uint32_t crc, const uint8_t* data, std::size_t n) {
  uLong c = crc;
  while (n > 0) {
    const auto step = static_cast<uInt>(std::min<std::size_t>(n, 1u << 30));
    c = crc32(c, data, step);
    data += step;
    n -= step;
  }
  return static_cast<uint32_t>(c);
}

std::vector<uint8_t> McapWriter::start(const std::string& profile, const std::string& library) {
  std::vector<uint8_t> b(kMagic, kMagic + sizeof kMagic);
  Out o{b};
  const std::size_t at = o.beginRecord(kHeader);
  o.str(profile);
  o.str(library);
  o.endRecord(at);
  pending_offset_ = b.size();
  return b;
}

uint16_t McapWriter::addSchema(const std::string& name, const std::string& encoding, const std::string& data) {
  const uint16_t id = next_schema_++;
  std::vector<uint8_t> rec;
  Out o{rec};
  const std::size_t at = o.beginRecord(kSchema);
  o.u16(id);
  o.str(name);
  o.str(encoding);
  o.str(data);  // uint32 length-prefixed bytes: the same layout as a string
  o.endRecord(at);
  pending_.insert(pending_.end(), rec.begin(), rec.end());
  schema_records_.push_back(std::move(rec));
  return id;
}

uint16_t McapWriter::addChannel(uint16_t schema_id, const std::string& topic, const std::string& message_encoding,
                                const std::map<std::string, std::string>& metadata) {
  const uint16_t id = next_channel_++;
  std::vector<uint8_t> rec;
  Out o{rec};
  const std::size_t at = o.beginRecord(kChannel);
  o.u16(id);
  o.u16(schema_id);
  o.str(topic);
  o.str(message_encoding);
  o.strMap(metadata);
  o.endRecord(at);
  pending_.insert(pending_.end(), rec.begin(), rec.end());
  channel_records_.push_back(std::move(rec));
  sequence_.push_back(0);
  channel_counts_.push_back(0);
  return id;
}

void McapWriter::addMetadata(const std::string& name, const std::map<std::string, std::string>& values) {
  Out o{pending_};
  const std::size_t from = pending_.size();
  const std::size_t at = o.beginRecord(kMetadata);
  o.str(name);
  o.strMap(values);
  o.endRecord(at);
  metadata_index_.push_back({pending_offset_ + from, pending_.size() - from, name});
  ++metadata_count_;
}

std::vector<uint8_t> McapWriter::takePending() {
  std::vector<uint8_t> out;
  out.swap(pending_);
  pending_offset_ += out.size();
  return out;
}

void McapWriter::addMessage(uint16_t channel_id, uint64_t log_time_ns, const uint8_t* data, std::size_t size) {
  if (channel_id >= sequence_.size()) return;  // not a channel of this file: never write a dangling reference
  chunk_index_[channel_id].emplace_back(log_time_ns, chunk_.size());
  Out o{chunk_};
  const std::size_t at = o.beginRecord(kMessage);
  o.u16(channel_id);
  o.u32(sequence_[channel_id]++);
  o.u64(log_time_ns);
  o.u64(log_time_ns);  // publish_time: not known apart from the log time
  o.raw(data, size);
  o.endRecord(at);
  if (chunk_messages_ == 0 || log_time_ns < chunk_start_) chunk_start_ = log_time_ns;
  if (chunk_messages_ == 0 || log_time_ns > chunk_end_) chunk_end_ = log_time_ns;
  ++chunk_messages_;
  ++channel_counts_[channel_id];
  if (message_count_ == 0 || log_time_ns < start_time_) start_time_ = log_time_ns;
  if (message_count_ == 0 || log_time_ns > end_time_) end_time_ = log_time_ns;
  ++message_count_;
}

std::vector<uint8_t> McapWriter::takeChunk(uint64_t file_offset) {
  std::vector<uint8_t> b;
  if (chunk_messages_ == 0) return b;
  std::vector<uint8_t> compressed;
  std::string compression;
  if (compression_ == Compression::kZstd) {
    compressed.resize(ZSTD_compressBound(chunk_.size()));
    const std::size_t n = ZSTD_compress(compressed.data(), compressed.size(), chunk_.data(), chunk_.size(), 3);
    if (ZSTD_isError(n) == 0) {
      compressed.resize(n);
      compression = "zstd";
    }
  }
  const std::vector<uint8_t>& records = compression.empty() ? chunk_ : compressed;
  Out o{b};
  const std::size_t at = o.beginRecord(kChunk);
  o.u64(chunk_start_);
  o.u64(chunk_end_);
  o.u64(chunk_.size());
  o.u32(mcapCrc(0, chunk_.data(), chunk_.size()));
  o.str(compression);
  o.u64(records.size());
  o.raw(records.data(), records.size());
  o.endRecord(at);
  ChunkIndex ci{chunk_start_, chunk_end_, file_offset, b.size(), 0, records.size(), chunk_.size(), {}, compression};
  for (const auto& [channel, entries] : chunk_index_) {
    ci.index_offsets.emplace_back(channel, file_offset + b.size());
    const std::size_t mi = o.beginRecord(kMessageIndex);
    o.u16(channel);
    o.u32(static_cast<uint32_t>(entries.size() * 16));
    for (const auto& [t, off] : entries) {
      o.u64(t);
      o.u64(off);
    }
    o.endRecord(mi);
  }
  ci.index_length = b.size() - ci.length;
  chunks_.push_back(std::move(ci));
  chunk_.clear();
  chunk_index_.clear();
  chunk_messages_ = 0;
  return b;
}

std::vector<uint8_t> McapWriter::finish(uint64_t file_offset, uint32_t data_crc) {
  std::vector<uint8_t> b;
  Out o{b};
  std::size_t at = o.beginRecord(kDataEnd);
  o.u32(data_crc);
  o.endRecord(at);
  const uint64_t summary_start = file_offset + b.size();
  struct Group {
    uint8_t op;
    uint64_t start, length;
  };
  std::vector<Group> groups;
  auto group = [&](uint8_t op, const auto& emit) {
    const std::size_t from = b.size();
    emit();
    if (b.size() > from) groups.push_back({op, file_offset + from, b.size() - from});
  };
  group(kSchema, [&] {
    for (const auto& r : schema_records_) o.raw(r.data(), r.size());
  });
  group(kChannel, [&] {
    for (const auto& r : channel_records_) o.raw(r.data(), r.size());
  });
  group(kStatistics, [&] {
    at = o.beginRecord(kStatistics);
    o.u64(message_count_);
    o.u16(static_cast<uint16_t>(schema_records_.size()));
    o.u32(static_cast<uint32_t>(channel_records_.size()));
    o.u32(0);  // attachments
    o.u32(metadata_count_);
    o.u32(static_cast<uint32_t>(chunks_.size()));
    o.u64(start_time_);
    o.u64(end_time_);
    o.u32(static_cast<uint32_t>(channel_counts_.size() * 10));
    for (std::size_t c = 0; c < channel_counts_.size(); ++c) {
      o.u16(static_cast<uint16_t>(c));
      o.u64(channel_counts_[c]);
    }
    o.endRecord(at);
  });
  group(kMetadataIndex, [&] {
    for (const MetadataIndex& m : metadata_index_) {
      at = o.beginRecord(kMetadataIndex);
      o.u64(m.offset);
      o.u64(m.length);
      o.str(m.name);
      o.endRecord(at);
    }
  });
  group(kChunkIndex, [&] {
    for (const ChunkIndex& ci : chunks_) {
      at = o.beginRecord(kChunkIndex);
      o.u64(ci.start_time);
      o.u64(ci.end_time);
      o.u64(ci.offset);
      o.u64(ci.length);
      o.u32(static_cast<uint32_t>(ci.index_offsets.size() * 10));
      for (const auto& [channel, off] : ci.index_offsets) {
        o.u16(channel);
        o.u64(off);
      }
      o.u64(ci.index_length);
      o.str(ci.compression);
      o.u64(ci.compressed);
      o.u64(ci.uncompressed);
      o.endRecord(at);
    }
  });
  const uint64_t summary_offset_start = file_offset + b.size();
  for (const Group& g : groups) {
    at = o.beginRecord(kSummaryOffset);
    o.u8(g.op);
    o.u64(g.start);
    o.u64(g.length);
    o.endRecord(at);
  }
  const std::size_t summary_from = static_cast<std::size_t>(summary_start - file_offset);
  o.u8(kFooter);
  o.u64(8 + 8 + 4);
  o.u64(groups.empty() ? 0 : summary_start);
  o.u64(groups.empty() ? 0 : summary_offset_start);
  o.u32(mcapCrc(0, b.data() + summary_from, b.size() - summary_from));
  o.raw(kMagic, sizeof kMagic);
  return b;
}

}  // namespace phalanx::host::record
