// The replay's MCAP reader (host/src/record/mcap_reader.cpp) on files the project's own encoder writes: every
// message and the session metadata come back; a file cut short reads up to its last whole chunk; a damaged chunk,
// a non-MCAP file and a non-regular file are refused by name; a negative zero keeps its sign through the JSON.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/record/mcap_reader.h"
#include "phalanx/host/record/mcap_session.h"
#include "phalanx/host/therapy/device.h"

namespace record = phalanx::host::record;
namespace protocol = phalanx::protocol;

namespace {

struct Written {
  std::vector<uint8_t> bytes;
  std::vector<std::size_t> chunk_starts, chunk_ends;  // file offsets of each chunk's first byte / after it
  uint64_t messages = 0;
};

/// A live pantograph recording of `cycles` cycles, a chunk per 10 cycles.
Written writePen(int cycles) {
  record::McapLayout l;
  l.device = "pantograph";
  l.samples = record::sampleColumnNames(protocol::kPantographLayout);
  l.setpoints = record::setpointColumnNames(protocol::kPantographLayout);
  l.header = {{"device", "pantograph"}, {"replay", {{"format_version", 1}}}};
  l.live = true;
  l.pen = true;
  l.pen_model = phalanx::pen::defaultModel<double>();
  record::McapSession s(l, nullptr);
  Written w;
  w.bytes = s.start();
  uint32_t crc = record::mcapCrc(0, w.bytes.data(), w.bytes.size());
  for (int i = 0; i < cycles; ++i) {
    record::CycleRecord c;
    c.t_s = 0.001 * (i + 1);
    c.host_ns = static_cast<uint64_t>(i + 1) * 1000000u;
    c.tel_seq = static_cast<uint16_t>(i);
    c.sample_count = 12;
    c.setpoint_count = 6;
    for (int k = 0; k < 6; ++k) c.sample[static_cast<std::size_t>(k)] = 0.001f * static_cast<float>(i % 7);
    c.setpoint[0] = i == 3 ? -0.0f : 0.01f * static_cast<float>(i);
    record::CommandExtras x;
    x.source = 0;
    x.gain_permille.fill(1000);
    s.addCycle(c, &x);
    if ((i + 1) % 10 == 0 || i + 1 == cycles) {
      const std::vector<uint8_t> chunk = s.takeChunk(w.bytes.size());
      crc = record::mcapCrc(crc, chunk.data(), chunk.size());
      w.chunk_starts.push_back(w.bytes.size());
      w.bytes.insert(w.bytes.end(), chunk.begin(), chunk.end());
      w.chunk_ends.push_back(w.bytes.size());
    }
  }
  w.messages = s.messageCount();
  const std::vector<uint8_t> tail = s.finish(w.bytes.size(), crc);
  w.bytes.insert(w.bytes.end(), tail.begin(), tail.end());
  return w;
}

std::string toFile(const std::vector<uint8_t>& b, std::size_t n, const char* name) {
  const std::string path = ::testing::TempDir() + "/" + name + std::to_string(::getpid()) + ".mcap";
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(n));
  return path;
}

std::size_t count(const record::McapContents& m, const std::string& topic) {
  std::size_t n = 0;
  for (const auto& msg : m.messages) n += m.topics.at(msg.channel) == topic ? 1 : 0;
  return n;
}

}  // namespace

TEST(McapReader, ReadsEveryMessageAndTheSessionMetadata) {
  const Written w = writePen(35);
  const std::string path = toFile(w.bytes, w.bytes.size(), "whole");
  record::McapContents m;
  ASSERT_EQ(record::readMcap(path, m), "");
  EXPECT_TRUE(m.complete);
  EXPECT_EQ(m.messages.size(), w.messages);
  EXPECT_EQ(count(m, "/phalanx/telemetry"), 35u);
  EXPECT_EQ(count(m, "/phalanx/pen/pose"), 35u);
  EXPECT_EQ(count(m, "/phalanx/pen/wrench"), 35u);
  const auto header = nlohmann::json::parse(m.metadata.at("phalanx_session").at("header"));
  EXPECT_EQ(header["replay"]["format_version"], 1);
  ::unlink(path.c_str());
}

TEST(McapReader, AFileCutShortReadsUpToItsLastWholeChunk) {
  const Written w = writePen(35);
  const std::size_t cut = w.chunk_ends[1] + (w.chunk_ends[2] - w.chunk_ends[1]) / 2;  // inside the third chunk
  const std::string path = toFile(w.bytes, cut, "cut");
  record::McapContents m;
  ASSERT_EQ(record::readMcap(path, m), "");
  EXPECT_FALSE(m.complete);
  EXPECT_EQ(count(m, "/phalanx/telemetry"), 20u);
  ::unlink(path.c_str());
}

TEST(McapReader, ADamagedChunkIsRefused) {
  Written w = writePen(35);
  // Past the Chunk record's opcode, length and header fields (9 + 28 + 4 + "zstd" + 8 = 53 bytes): its data.
  w.bytes[w.chunk_starts[0] + 60] ^= 0x21;
  const std::string path = toFile(w.bytes, w.bytes.size(), "damaged");
  record::McapContents m;
  EXPECT_NE(record::readMcap(path, m).find("damaged MCAP file"), std::string::npos);
  ::unlink(path.c_str());
}

TEST(McapReader, NotMcapAndNotARegularFileAreRefused) {
  const std::vector<uint8_t> csv{'t', '_', 's', ',', 'x', '\n', '1', '\n', '2', '\n'};
  const std::string path = toFile(csv, csv.size(), "csv");
  record::McapContents m;
  EXPECT_NE(record::readMcap(path, m).find("not an MCAP file"), std::string::npos);
  EXPECT_NE(record::readMcap("/dev/null", m).find("not a regular file"), std::string::npos);
  ::unlink(path.c_str());
}

TEST(McapReader, ANegativeZeroSetpointKeepsItsSign) {
  const Written w = writePen(5);
  const std::string path = toFile(w.bytes, w.bytes.size(), "negzero");
  record::McapContents m;
  ASSERT_EQ(record::readMcap(path, m), "");
  std::vector<double> sp;
  for (const auto& msg : m.messages) {
    if (m.topics.at(msg.channel) == "/phalanx/command") sp.push_back(nlohmann::json::parse(msg.data)["setpoint_torque0_Nm"].get<double>());
  }
  ASSERT_EQ(sp.size(), 5u);
  EXPECT_TRUE(sp[3] == 0.0 && std::signbit(sp[3]));
  EXPECT_FALSE(std::signbit(sp[0]));
  ::unlink(path.c_str());
}
