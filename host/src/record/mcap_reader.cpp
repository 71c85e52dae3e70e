#include "phalanx/host/record/mcap_reader.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zstd.h>

#include <cerrno>
#include <cstring>

#include "phalanx/host/record/mcap_writer.h"

namespace phalanx::host::record {
namespace {

constexpr uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
enum Op : uint8_t { kChannel = 0x04, kMessage = 0x05, kChunk = 0x06, kMetadata = 0x0C, kDataEnd = 0x0F, kFooter = 0x02 };

/// Bounds-checked little-endian reads over one record's body; ok turns false on a read past its end.
struct In {
  const uint8_t* p;
  std::size_t n;
  std::size_t at = 0;
  bool ok = true;
  bool need(std::size_t k) {
    if (!ok || n - at < k) ok = false;
    return ok;
  }
  uint64_t le(std::size_t k) {  // k <= 8: a little-endian unsigned integer of k bytes
    if (k > 8) ok = false;
    if (!need(k)) return 0;
    uint64_t v = 0;
    for (std::size_t i = 0; i < k; ++i) v |= static_cast<uint64_t>(p[at + i]) << (8 * i);
    at += k;
    return v;
  }
  std::string bytes(std::size_t k) {
    if (!need(k)) return {};
    std::string s(reinterpret_cast<const char*>(p + at), k);
    at += k;
    return s;
  }
  std::string str() { return bytes(static_cast<std::size_t>(le(4))); }
  std::map<std::string, std::string> strMap() {
    const std::size_t len = static_cast<std::size_t>(le(4));
    std::map<std::string, std::string> m;
    if (!need(len)) return m;
    In sub{p + at, len};
    while (sub.ok && sub.at < sub.n) {
      std::string k = sub.str();
      m[k] = sub.str();
    }
    ok = sub.ok;
    at += len;
    return m;
  }
};

std::string readFile(const std::string& path, std::vector<uint8_t>& out) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) return "cannot read " + path + ": " + std::strerror(errno);
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return "not a recording: " + path + " is not a regular file";
  }
  out.resize(static_cast<std::size_t>(st.st_size));
  std::size_t got = 0;
  while (got < out.size()) {
    const ssize_t r = ::read(fd, out.data() + got, out.size() - got);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) break;
    got += static_cast<std::size_t>(r);
  }
  ::close(fd);
  out.resize(got);
  return {};
}

class Parser {
 public:
  Parser(const std::string& path, McapContents& out) : path_(path), out_(out) {}

  /// Records of a data section (the file's, or a chunk's); stops at a record cut short (in_chunk: an error).
  std::string records(const uint8_t* p, std::size_t n, bool in_chunk) {
    std::size_t at = 0;
    while (at < n) {
      if (n - at < 9) return in_chunk ? bad("a chunk's records end inside a record") : std::string();
      const uint8_t op = p[at];
      uint64_t len = 0;
      for (int i = 0; i < 8; ++i) len |= static_cast<uint64_t>(p[at + 1 + i]) << (8 * i);
      if (len > n - at - 9) return in_chunk ? bad("a chunk holds a record longer than the chunk") : std::string();
      In body{p + at + 9, static_cast<std::size_t>(len)};
      if (std::string err = record(op, body); !err.empty()) return err;
      at += 9 + static_cast<std::size_t>(len);
      if (!in_chunk && (op == kDataEnd || op == kFooter)) {
        out_.complete = true;
        return {};
      }
    }
    return {};
  }

 private:
  std::string bad(const std::string& what) const { return "damaged MCAP file " + path_ + ": " + what; }

  std::string record(uint8_t op, In& b) {
    if (op == kChannel) {
      const auto id = static_cast<uint16_t>(b.le(2));
      b.le(2);
      out_.topics[id] = b.str();
    } else if (op == kMessage) {
      McapMessage m;
      m.channel = static_cast<uint16_t>(b.le(2));
      b.le(4);
      m.log_time = b.le(8);
      b.le(8);
      if (b.ok) m.data = b.bytes(b.n - b.at);
      out_.messages.push_back(std::move(m));
    } else if (op == kMetadata) {
      std::string name = b.str();
      out_.metadata[name] = b.strMap();
    } else if (op == kChunk) {
      return chunk(b);
    }
    return b.ok ? std::string() : bad("a record (opcode " + std::to_string(op) + ") is shorter than its fields");
  }

  std::string chunk(In& b) {
    b.le(8);  // message start time
    b.le(8);  // message end time
    const uint64_t size = b.le(8);
    const auto crc = static_cast<uint32_t>(b.le(4));
    const std::string compression = b.str();
    const uint64_t len = b.le(8);
    if (!b.ok || len > b.n - b.at) return bad("a chunk is shorter than its header says");
    if (size > (1ull << 31)) return bad("a chunk claims " + std::to_string(size) + " bytes uncompressed");
    const uint8_t* data = b.p + b.at;
    std::vector<uint8_t> plain;
    if (compression == "zstd") {
      plain.resize(static_cast<std::size_t>(size));
      const std::size_t r = ZSTD_decompress(plain.data(), plain.size(), data, static_cast<std::size_t>(len));
      if (ZSTD_isError(r) || r != size) return bad("a zstd chunk does not decompress to its stated size");
    } else if (compression.empty()) {
      if (len != size) return bad("an uncompressed chunk's sizes differ");
      plain.assign(data, data + len);
    } else {
      return "cannot read " + path_ + ": chunk compression '" + compression + "' (this reader knows zstd and none)";
    }
    if (crc != 0 && mcapCrc(0, plain.data(), plain.size()) != crc) return bad("a chunk's CRC-32 does not match");
    return records(plain.data(), plain.size(), true);
  }

  const std::string& path_;
  McapContents& out_;
};

}  // namespace

std::string readMcap(const std::string& path, McapContents& out) {
  std::vector<uint8_t> file;
  if (std::string err = readFile(path, file); !err.empty()) return err;
  if (file.size() < sizeof kMagic || std::memcmp(file.data(), kMagic, sizeof kMagic) != 0) {
    return "not an MCAP file: " + path + " does not start with the MCAP magic";
  }
  Parser p(path, out);
  return p.records(file.data() + sizeof kMagic, file.size() - sizeof kMagic, false);
}

}  // namespace phalanx::host::record
