#pragma once
/// A small MCAP reader for `phalanx record replay` (docs/records.md, "Replay"): reads a file in order, like the
/// `mcap` package's NonSeekingReader, checking what the specification lets it check: the magic, every record's
/// length, every chunk's compression (none or zstd), size and CRC-32. Messages inside and outside chunks, schemas
/// and channels wherever they are, Metadata records; the summary section is not needed and not read.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace phalanx::host::record {

struct McapMessage {
  uint16_t channel = 0;
  uint64_t log_time = 0;
  std::string data;
};

struct McapContents {
  std::map<uint16_t, std::string> topics;  ///< channel id → topic
  std::map<std::string, std::map<std::string, std::string>> metadata;  ///< Metadata records by name
  std::vector<McapMessage> messages;       ///< in file order
  bool complete = false;                   ///< the data section ended with Data End (a closed file)
};

/// "" or what is wrong with the file (naming it): not a regular file, not MCAP, a damaged chunk, … A file cut
/// short (a killed recorder) is not an error: its whole records are read and complete stays false.
std::string readMcap(const std::string& path, McapContents& out);

}  // namespace phalanx::host::record
