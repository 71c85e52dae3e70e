// Session records: framing, checksums, torn tails, damaged records, the writer thread, CSV export; a failing
// records disk (a real small tmpfs), files that are not records, exports that must not destroy their input.
#include <gtest/gtest.h>
#include <dirent.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>

#include "phalanx/host/record/record_reader.h"
#include "phalanx/host/record/record_writer.h"
#include "../support/small_tmpfs.h"

using namespace phalanx::host::record;

namespace {

std::string tempPath(const char* tag) {
  char path[] = "/tmp/phalanx-rec-XXXXXX";
  const int fd = mkstemp(path);
  close(fd);
  unlink(path);
  return std::string(path) + tag;
}

CycleRecord cycle(int i) {
  CycleRecord c;
  c.host_ns = 1000000ull * static_cast<uint64_t>(i);
  c.t_s = 0.001 * i;
  c.device_time_us = 1000ull * static_cast<uint64_t>(i);
  c.tel_seq = static_cast<uint16_t>(i);
  c.cmd_seq = static_cast<uint16_t>(i + 7);
  c.fault_bits = static_cast<uint16_t>(i % 3);
  c.tel_mode = 1;
  c.cmd_mode = 2;
  c.sample_count = 25;
  c.setpoint_count = 5;
  c.aux_count = 3;
  for (int k = 0; k < 25; ++k) c.sample[k] = static_cast<float>(i) * 0.5f + static_cast<float>(k);
  for (int k = 0; k < 5; ++k) c.setpoint[k] = -static_cast<float>(k) * 0.25f;
  for (int k = 0; k < 3; ++k) c.aux[k] = static_cast<float>(k + i);
  return c;
}

std::string writeSession(int cycles, bool footer) {
  const std::string path = tempPath(".phrec");
  RecordWriter w;
  EXPECT_EQ(w.open(path, {{"device", "test"}, {"samples", {"a", "b"}}}), "");
  for (int i = 0; i < cycles; ++i) EXPECT_TRUE(w.pushCycle(cycle(i)));
  w.pushEvent(0.5, "api-exercise", {{"exercise", "assessment"}});
  w.close(footer ? nlohmann::json{{"ok", true}} : nlohmann::json(nullptr));
  return path;
}

std::vector<char> readAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void writeAll(const std::string& path, const std::vector<char>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

}  // namespace

TEST(SessionRecord, RoundTripsEveryFieldOfEveryCycle) {
  const std::string path = writeSession(500, true);
  SessionRecord rec;
  ASSERT_EQ(readRecord(path, rec), "");
  ASSERT_EQ(rec.cycles.size(), 500u);
  EXPECT_TRUE(rec.complete());
  EXPECT_FALSE(rec.torn_tail);
  EXPECT_EQ(rec.bad_records, 0u);
  EXPECT_EQ(rec.header["device"], "test");
  EXPECT_EQ(rec.footer["cycles_written"], 500);
  ASSERT_EQ(rec.events.size(), 1u);
  EXPECT_EQ(rec.events[0]["exercise"], "assessment");
  for (int i = 0; i < 500; ++i) {
    const CycleRecord e = cycle(i);
    const CycleRecord& g = rec.cycles[static_cast<size_t>(i)];
    EXPECT_EQ(g.host_ns, e.host_ns);
    EXPECT_EQ(g.t_s, e.t_s);
    EXPECT_EQ(g.tel_seq, e.tel_seq);
    EXPECT_EQ(g.cmd_seq, e.cmd_seq);
    EXPECT_EQ(g.fault_bits, e.fault_bits);
    EXPECT_EQ(g.sample, e.sample);
    EXPECT_EQ(g.setpoint, e.setpoint);
    EXPECT_EQ(g.aux_count, 3);
    EXPECT_EQ(g.aux[2], e.aux[2]);
  }
  unlink(path.c_str());
}

TEST(SessionRecord, EveryTruncationPointLeavesAReadablePrefix) {
  const std::string path = writeSession(20, false);
  const std::vector<char> full = readAll(path);
  SessionRecord whole;
  ASSERT_EQ(readRecord(path, whole), "");
  size_t previous = 0;
  for (size_t n = 8; n <= full.size(); ++n) {
    SessionRecord rec;
    ASSERT_EQ(parseRecord(std::vector<uint8_t>(full.begin(), full.begin() + static_cast<long>(n)), rec), "") << n;
    // Cycles only ever grow with the prefix, and every decoded cycle is the original one.
    ASSERT_GE(rec.cycles.size(), previous) << n;
    previous = rec.cycles.size();
    for (size_t i = 0; i < rec.cycles.size(); ++i) ASSERT_EQ(rec.cycles[i].tel_seq, i);
    EXPECT_EQ(rec.bad_records, 0u) << "a torn tail is not a damaged record, at " << n;
  }
  EXPECT_EQ(previous, 20u);
  unlink(path.c_str());
}

TEST(SessionRecord, ADamagedRecordCostsThatRecordOnly) {
  const std::string path = writeSession(100, true);
  std::vector<char> bytes = readAll(path);
  bytes[bytes.size() / 2] = static_cast<char>(bytes[bytes.size() / 2] ^ 0x5A);  // one flipped byte mid-file
  writeAll(path, bytes);
  SessionRecord rec;
  ASSERT_EQ(readRecord(path, rec), "");
  EXPECT_EQ(rec.cycles.size(), 99u);
  EXPECT_EQ(rec.bad_records, 1u);
  EXPECT_TRUE(rec.complete()) << "records after the damage are still read";
  unlink(path.c_str());
}

TEST(SessionRecord, RefusesAFileThatIsNotARecord) {
  const std::string path = tempPath(".txt");
  writeAll(path, {'h', 'e', 'l', 'l', 'o', '\n', 'x', 'y', 'z'});
  SessionRecord rec;
  EXPECT_NE(readRecord(path, rec).find("not a Phalanx session record"), std::string::npos);
  unlink(path.c_str());
}

TEST(SessionRecordWriter, NeverOverwritesAnExistingRecord) {
  const std::string path = writeSession(3, true);
  RecordWriter w;
  EXPECT_NE(w.open(path, {}).find("cannot create"), std::string::npos);
  unlink(path.c_str());
}

TEST(SessionRecordWriter, AFullQueueDropsAndCountsInsteadOfBlocking) {
  const std::string path = tempPath(".phrec");
  WriterConfig cfg;
  cfg.queue_cycles = 8;
  cfg.flush_period_ms = 60000;  // the writer thread sleeps: the queue fills
  RecordWriter w(cfg);
  ASSERT_EQ(w.open(path, {}), "");
  int accepted = 0;
  for (int i = 0; i < 100; ++i) accepted += w.pushCycle(cycle(i)) ? 1 : 0;
  EXPECT_EQ(accepted, 8);
  EXPECT_EQ(w.cyclesDropped(), 92u);
  w.close(nlohmann::json::object());
  SessionRecord rec;
  ASSERT_EQ(readRecord(path, rec), "");
  EXPECT_EQ(rec.cycles.size(), 8u);
  EXPECT_EQ(rec.footer["cycles_dropped"], 92);
  bool gap_event = false;
  for (const auto& e : rec.events) gap_event |= e["kind"] == "record-gap";
  EXPECT_TRUE(gap_event) << "dropped cycles must be visible in the record itself";
  unlink(path.c_str());
}

TEST(SessionRecordWriter, DataReachesTheFileWithinTheFlushPeriod) {
  const std::string path = tempPath(".phrec");
  RecordWriter w;  // default: write(2) every 20 ms
  ASSERT_EQ(w.open(path, {}), "");
  for (int i = 0; i < 10; ++i) w.pushCycle(cycle(i));
  // Poll the file from outside (what a reader after kill -9 would see): bounded wait, not a timing assertion.
  SessionRecord rec;
  for (int tries = 0; tries < 200 && rec.cycles.size() < 10; ++tries) {
    usleep(10000);
    ASSERT_EQ(readRecord(path, rec), "");
  }
  EXPECT_EQ(rec.cycles.size(), 10u);
  EXPECT_FALSE(rec.complete());
  w.close();
  unlink(path.c_str());
}

TEST(SessionRecordExport, CsvHasAHeaderAndOneRowPerCycleWithNamedColumns) {
  const std::string path = writeSession(50, true);
  SessionRecord rec;
  ASSERT_EQ(readRecord(path, rec), "");
  const std::string csv = path + ".csv";
  ASSERT_EQ(exportCsv(rec, csv), "");
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line.rfind("t_s,host_ns,device_time_us", 0), 0u);
  EXPECT_NE(line.find(",a,b,sample2"), std::string::npos) << line;
  const size_t columns = static_cast<size_t>(std::count(line.begin(), line.end(), ',')) + 1;
  EXPECT_EQ(columns, 10u + 25u + 5u + 3u);
  int rows = 0;
  while (std::getline(in, line)) {
    ++rows;
    EXPECT_EQ(static_cast<size_t>(std::count(line.begin(), line.end(), ',')) + 1, columns);
  }
  EXPECT_EQ(rows, 50);
  unlink(path.c_str());
  unlink(csv.c_str());
}

namespace {
std::size_t fileSize(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 ? static_cast<std::size_t>(st.st_size) : 0;
}
}  // namespace

// Issue: on a 2 MB tmpfs a session record silently stopped growing. The first write error must be latched and
// reported, the file must end at its last whole record, and every cycle must be counted as written or lost.
TEST(SessionRecordWriter, AFullDiskIsReportedAndEveryCycleIsAccountedFor) {
  phalanx::test::SmallTmpfs fs(64 * 1024);
  if (!fs.skipReason().empty()) GTEST_SKIP() << fs.skipReason();
  const std::string path = fs.dir() + "/full.phrec";
  WriterConfig cfg;
  cfg.queue_cycles = 4096;  // holds every cycle below: none is dropped, all reach the writer
  RecordWriter w(cfg);
  ASSERT_EQ(w.open(path, {{"device", "test"}}), "");
  constexpr int kCycles = 2000;  // ≈ 340 kB of cycle records for a 64 kB filesystem
  for (int i = 0; i < kCycles; ++i) ASSERT_TRUE(w.pushCycle(cycle(i)));
  for (int tries = 0; tries < 1000 && !w.failed(); ++tries) usleep(10000);  // bound only
  ASSERT_TRUE(w.failed()) << "the writer never noticed the full disk";
  const std::size_t size_at_failure = fileSize(path);
  for (int i = kCycles; i < kCycles + 100; ++i) w.pushCycle(cycle(i));  // after the failure: lost, not written
  w.close(nlohmann::json{{"ok", true}});
  EXPECT_NE(w.error().find("No space left on device"), std::string::npos) << w.error();
  EXPECT_NE(w.error().find(path), std::string::npos) << "the error names the file: " << w.error();
  EXPECT_EQ(w.cyclesWritten() + w.cyclesLost(), static_cast<uint64_t>(kCycles + 100));
  EXPECT_GE(w.cyclesLost(), 100u);
  EXPECT_EQ(w.cyclesDropped(), 0u);
  EXPECT_EQ(fileSize(path), size_at_failure) << "nothing is written after the failure";
  SessionRecord rec;
  ASSERT_EQ(readRecord(path, rec), "");
  EXPECT_EQ(rec.cycles.size(), w.cyclesWritten()) << "cycles counted as written are exactly those in the file";
  EXPECT_GT(rec.cycles.size(), 0u);
  EXPECT_FALSE(rec.torn_tail) << "the file was cut back to its last whole record";
  EXPECT_EQ(rec.bad_records, 0u);
  EXPECT_FALSE(rec.complete()) << "no footer on a disk that failed";
  for (size_t i = 0; i < rec.cycles.size(); ++i) ASSERT_EQ(rec.cycles[i].tel_seq, i) << "a contiguous prefix";
}

TEST(SessionRecordWriter, AHeaderThatCannotBeWrittenFailsTheStartAndLeavesNoFile) {
  phalanx::test::SmallTmpfs fs(16 * 1024);
  if (!fs.skipReason().empty()) GTEST_SKIP() << fs.skipReason();
  {
    std::ofstream fill(fs.dir() + "/fill", std::ios::binary);  // fill the filesystem: files still get created
    const std::string block(4096, 'x');
    for (int i = 0; i < 64 && fill; ++i) fill.write(block.data(), static_cast<std::streamsize>(block.size()));
  }
  const std::string path = fs.dir() + "/s.phrec";
  RecordWriter w;
  ASSERT_EQ(w.create(path), "") << "creating the (empty) file works on a full tmpfs";
  const std::string err = w.start({{"device", "test"}, {"pad", std::string(8192, 'p')}});
  EXPECT_NE(err.find("No space left on device"), std::string::npos) << err;
  EXPECT_TRUE(w.failed());
  w.close();
  EXPECT_NE(::access(path.c_str(), F_OK), 0) << "a record without its header is removed";
}

TEST(SessionRecordWriter, ACreatedRecordThatNeverStartedIsRemoved) {
  const std::string path = tempPath(".phrec");
  {
    RecordWriter w;
    ASSERT_EQ(w.create(path), "");
    ASSERT_EQ(::access(path.c_str(), F_OK), 0);
    int err_no = 0;
    RecordWriter other;
    EXPECT_NE(other.create(path, &err_no), "");
    EXPECT_EQ(err_no, EEXIST);
  }
  EXPECT_NE(::access(path.c_str(), F_OK), 0) << "the session ended before its first cycle: no empty record is left";
}

// Issue: `phalanx record info /dev/zero` aborted with std::bad_alloc.
TEST(SessionRecord, AFileThatIsNotARegularFileIsRefusedWithoutReadingIt) {
  SessionRecord rec;
  const std::string zero = readRecord("/dev/zero", rec);
  EXPECT_NE(zero.find("not a record: /dev/zero is a character device"), std::string::npos) << zero;
  const std::string dir = readRecord("/tmp", rec);
  EXPECT_NE(dir.find("not a record: /tmp is a directory"), std::string::npos) << dir;
  const std::string fifo = tempPath(".fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string f = readRecord(fifo, rec);  // must neither block on the open nor read forever
  EXPECT_NE(f.find("is a FIFO"), std::string::npos) << f;
  ::unlink(fifo.c_str());
  EXPECT_NE(readRecord("/nonexistent/x.phrec", rec).find("cannot read /nonexistent/x.phrec"), std::string::npos);
}

// Issue: `phalanx record export x.phrec --csv --out x.phrec` destroyed the record.
TEST(SessionRecordExport, NeverWritesOverTheRecordItExports) {
  const std::string path = writeSession(30, true);
  const std::vector<char> before = readAll(path);
  const std::string link = path + ".link", hard = path + ".hard";
  ASSERT_EQ(::symlink(path.c_str(), link.c_str()), 0);
  ASSERT_EQ(::link(path.c_str(), hard.c_str()), 0);
  SessionRecord rec;
  ASSERT_EQ(readRecord(path, rec), "");
  for (const std::string& out : {path, link, hard}) {
    const std::string err = exportCsv(rec, out);
    EXPECT_NE(err.find("refusing to write " + out), std::string::npos) << out << ": " << err;
  }
  SessionRecord through_link;  // read through the symlink, exported onto the real path
  ASSERT_EQ(readRecord(link, through_link), "");
  EXPECT_NE(exportCsv(through_link, path).find("refusing"), std::string::npos);
  EXPECT_EQ(readAll(path), before) << "the record is untouched";
  ASSERT_EQ(readRecord(path, rec), "");
  EXPECT_EQ(rec.cycles.size(), 30u);
  for (const std::string& f : {path, link, hard}) ::unlink(f.c_str());
}

TEST(SessionRecordExport, AFailedExportLeavesTheExistingFileAsItWas) {
  phalanx::test::SmallTmpfs fs(64 * 1024);
  if (!fs.skipReason().empty()) GTEST_SKIP() << fs.skipReason();
  const std::string path = writeSession(3000, true);  // a ≈ 1 MB CSV: does not fit
  SessionRecord rec;
  ASSERT_EQ(readRecord(path, rec), "");
  const std::string out = fs.dir() + "/old.csv";
  std::ofstream(out) << "an earlier export\n";
  const std::string err = exportCsv(rec, out);
  EXPECT_NE(err.find("No space left on device"), std::string::npos) << err;
  std::ifstream in(out);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "an earlier export") << "the existing file is untouched";
  int files = 0;
  if (DIR* d = ::opendir(fs.dir().c_str())) {
    while (const dirent* e = ::readdir(d)) files += e->d_name[0] == '.' && (e->d_name[1] == 0 || e->d_name[1] == '.') ? 0 : 1;
    ::closedir(d);
  }
  EXPECT_EQ(files, 1) << "no temporary file is left behind";
  ::unlink(path.c_str());
}
