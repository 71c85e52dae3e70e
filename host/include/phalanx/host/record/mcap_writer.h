#pragma once
/// MCAP (https://mcap.dev, spec "MCAP format", version 0) encoder: builds the bytes of a file in memory, one
/// chunk at a time; the caller writes them (and so decides about write errors, see csv_recorder.cpp and
/// mcap_session.cpp). Hand-written: Debian ships no MCAP library for C++ (docs/records.md, "MCAP").
///
/// A file grows as: magic, Header, the Schemas and Channels (in the data section, before any chunk, so a file cut
/// short still names every channel), then per takeChunk() one Chunk (uncompressed or zstd, with the CRC-32 of its
/// records) followed by its Message Index records. finish() appends Data End (with the CRC of the data section),
/// the summary section (Schemas, Channels, Statistics, Chunk Indexes), the Summary Offsets, the Footer (with the
/// summary CRC) and the closing magic. A file that was never finished (the daemon killed) ends after its last
/// whole chunk: a reader that reads the data section in order (mcap's non-seeking readers, `mcap recover`) gets
/// every message up to it.
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace phalanx::host::record {

class McapWriter {
 public:
  enum class Compression { kNone, kZstd };
  explicit McapWriter(Compression compression = Compression::kZstd) : compression_(compression) {}

  /// Magic and Header record; the first bytes of the file.
  std::vector<uint8_t> start(const std::string& profile, const std::string& library);
  /// Registers a schema (encoding "ros2msg", "jsonschema", …) and returns its id (≥ 1). The record goes into the
  /// bytes of the next takePending().
  uint16_t addSchema(const std::string& name, const std::string& encoding, const std::string& data);
  /// Registers a channel on a schema (message encoding "cdr", "json") and returns its id.
  uint16_t addChannel(uint16_t schema_id, const std::string& topic, const std::string& message_encoding,
                      const std::map<std::string, std::string>& metadata = {});
  /// Records written outside chunks since the last call (schemas, channels, metadata): write them before the
  /// next chunk.
  std::vector<uint8_t> takePending();
  /// A Metadata record (outside chunks; goes with takePending()).
  void addMetadata(const std::string& name, const std::map<std::string, std::string>& values);
  /// Appends a Message to the open chunk. log_time_ns: nanoseconds since the Unix epoch.
  void addMessage(uint16_t channel_id, uint64_t log_time_ns, const uint8_t* data, std::size_t size);
  void addMessage(uint16_t channel_id, uint64_t log_time_ns, const std::vector<uint8_t>& data) {
    addMessage(channel_id, log_time_ns, data.data(), data.size());
  }
  void addMessage(uint16_t channel_id, uint64_t log_time_ns, const std::string& data) {
    addMessage(channel_id, log_time_ns, reinterpret_cast<const uint8_t*>(data.data()), data.size());
  }
  /// Messages in the open chunk.
  std::size_t chunkMessages() const { return chunk_messages_; }
  /// Closes the open chunk: the Chunk record and its Message Index records, to be written at file offset
  /// `file_offset` (where the file ends now). Empty when the chunk has no message. An error of the caller's
  /// write is the caller's: it must not call finish() for a file that lost a chunk.
  std::vector<uint8_t> takeChunk(uint64_t file_offset);
  /// Data End, summary, summary offsets, footer and magic, to be written at file_offset (the end of the file
  /// after every chunk). data_crc: CRC-32 of every byte of the file before this point (0: not computed).
  std::vector<uint8_t> finish(uint64_t file_offset, uint32_t data_crc);
  uint64_t messageCount() const { return message_count_; }

 private:
  struct ChunkIndex {
    uint64_t start_time, end_time, offset, length, index_length, compressed, uncompressed;
    std::vector<std::pair<uint16_t, uint64_t>> index_offsets;
    std::string compression;
  };
  Compression compression_;
  std::vector<uint8_t> pending_;  // records outside chunks not yet taken
  std::vector<std::vector<uint8_t>> schema_records_, channel_records_;
  uint16_t next_schema_ = 1, next_channel_ = 0;
  std::vector<uint32_t> sequence_;  // per channel
  std::vector<uint64_t> channel_counts_;
  uint32_t metadata_count_ = 0;
  // Metadata Index records of the summary: where each Metadata record lands, the pending bytes being written
  // right after start() (and after the previous takePending()).
  struct MetadataIndex {
    uint64_t offset, length;
    std::string name;
  };
  std::vector<MetadataIndex> metadata_index_;
  uint64_t pending_offset_ = 0;
  // The open chunk.
  std::vector<uint8_t> chunk_;
  std::map<uint16_t, std::vector<std::pair<uint64_t, uint64_t>>> chunk_index_;  // channel → (time, offset)
  std::size_t chunk_messages_ = 0;
  uint64_t chunk_start_ = 0, chunk_end_ = 0;
  std::vector<ChunkIndex> chunks_;
  uint64_t message_count_ = 0, start_time_ = 0, end_time_ = 0;
};

/// CRC-32 (zlib) of bytes, continuing crc.
uint32_t mcapCrc(uint32_t crc, const uint8_t* data, std::size_t n);

}  // namespace phalanx::host::record
