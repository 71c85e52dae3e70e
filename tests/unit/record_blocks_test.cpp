// .phrec format version 2 (compressed cycle blocks, docs/records.md): every field round-trips, every truncation
// point reads as a valid prefix, a damaged block costs that block and the rest of the file is read.
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "phalanx/host/record/record_reader.h"
#include "phalanx/host/record/record_writer.h"

using namespace phalanx::host::record;

namespace {

CycleRecord cycle(int i) {
  CycleRecord c;
  c.host_ns = 1000000ull * static_cast<uint64_t>(i) + 17;
  c.t_s = 0.001 * i;
  c.device_time_us = 1000ull * static_cast<uint64_t>(i);
  c.tel_seq = static_cast<uint16_t>(i);
  c.cmd_seq = static_cast<uint16_t>(i + 1);
  c.fault_bits = static_cast<uint16_t>(i % 7 == 0 ? 4 : 0);
  c.sample_count = 25;
  c.setpoint_count = 5;
  c.aux_count = 22;
  for (int k = 0; k < 25; ++k) c.sample[k] = 0.3f * static_cast<float>(k) + 1e-3f * static_cast<float>(i);
  for (int k = 0; k < 5; ++k) c.setpoint[k] = -0.25f * static_cast<float>(k);
  for (int k = 0; k < 22; ++k) c.aux[k] = static_cast<float>(k * i);
  return c;
}

std::string writeBlocks(int cycles) {
  char tmpl[] = "/tmp/phalanx-blocks-XXXXXX";
  const int fd = mkstemp(tmpl);
  close(fd);
  unlink(tmpl);
  WriterConfig cfg;
  cfg.cycle_blocks = true;
  RecordWriter w(cfg);
  EXPECT_EQ(w.open(tmpl, {{"device", "test"}, {"format_version", 2}}), "");
  for (int i = 0; i < cycles; ++i) {
    EXPECT_TRUE(w.pushCycle(cycle(i)));
    if (i % 37 == 0) usleep(2000);  // several flushes: several blocks
  }
  w.close(nlohmann::json{{"ok", true}});
  return tmpl;
}

std::vector<uint8_t> readAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST(RecordBlocks, EveryFieldOfEveryCycleRoundTripsAndTheFileIsSmaller) {
  const std::string path = writeBlocks(2000);
  SessionRecord rec;
  ASSERT_EQ(readRecord(path, rec), "");
  ASSERT_EQ(rec.cycles.size(), 2000u);
  EXPECT_EQ(rec.bad_records, 0u);
  EXPECT_TRUE(rec.complete());
  for (int i = 0; i < 2000; ++i) {
    const CycleRecord e = cycle(i);
    const CycleRecord& g = rec.cycles[static_cast<size_t>(i)];
    ASSERT_EQ(g.host_ns, e.host_ns);
    ASSERT_EQ(g.t_s, e.t_s);
    ASSERT_EQ(g.device_time_us, e.device_time_us);
    ASSERT_EQ(g.tel_seq, e.tel_seq);
    ASSERT_EQ(g.cmd_seq, e.cmd_seq);
    ASSERT_EQ(g.fault_bits, e.fault_bits);
    ASSERT_EQ(g.sample, e.sample);
    ASSERT_EQ(g.setpoint, e.setpoint);
    ASSERT_EQ(g.aux, e.aux);
  }
  const std::size_t plain = 2000u * (kRecordOverhead + 38u + 4u * (25u + 5u + 22u));
  EXPECT_LT(readAll(path).size(), plain / 2) << "format 2 is at least 2x smaller than format 1 here";
  unlink(path.c_str());
}

TEST(RecordBlocks, EveryTruncationPointLeavesAReadablePrefixAndADamagedBlockCostsOnlyItself) {
  const std::string path = writeBlocks(300);
  const std::vector<uint8_t> full = readAll(path);
  size_t previous = 0;
  for (size_t n = 8; n <= full.size(); n += 7) {
    SessionRecord rec;
    ASSERT_EQ(parseRecord(std::vector<uint8_t>(full.begin(), full.begin() + static_cast<long>(n)), rec), "");
    ASSERT_GE(rec.cycles.size(), previous);
    previous = rec.cycles.size();
    for (size_t i = 0; i < rec.cycles.size(); ++i) ASSERT_EQ(rec.cycles[i].tel_seq, i);
    ASSERT_EQ(rec.bad_records, 0u) << n;
  }
  std::vector<uint8_t> bad = full;
  bad[bad.size() / 2] ^= 0x5A;
  SessionRecord rec;
  ASSERT_EQ(parseRecord(bad, rec), "");
  EXPECT_EQ(rec.bad_records, 1u);
  EXPECT_LT(rec.cycles.size(), 300u);
  // The cycles before and after the damaged block are read, in order (how many a block holds depends on the
  // writer's flushes, so the count is not asserted).
  for (size_t i = 1; i < rec.cycles.size(); ++i) ASSERT_GT(rec.cycles[i].tel_seq, rec.cycles[i - 1].tel_seq);
  EXPECT_TRUE(rec.complete()) << "records after the damage are still read";
  unlink(path.c_str());
}
