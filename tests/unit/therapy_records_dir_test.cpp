// The records directory's names: a patient's records are matched by the whole parsed name (never a prefix) and
// ordered by start second, then sequence number (never by string order, which puts "-10" before "-2" and a
// second's first record after its later ones).
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <string>
#include <vector>

#include "phalanx/host/therapy/records_dir.h"

using namespace phalanx::host::therapy;

namespace {

struct TempDir {
  TempDir() {
    char tmpl[] = "/tmp/phalanx-records-XXXXXX";
    path = mkdtemp(tmpl) != nullptr ? tmpl : "/tmp";
  }
  ~TempDir() { std::system(("rm -rf " + path).c_str()); }
  void touch(const std::string& name) const { std::ofstream(path + "/" + name) << ""; }
  std::string path;
};

}  // namespace

TEST(RecordName, ParsesPatientStampAndSequence) {
  RecordName n;
  ASSERT_TRUE(parseRecordName("demo-001-20240102T030405Z-12.phrec", n));
  EXPECT_EQ(n.patient, "demo-001");
  EXPECT_EQ(n.stamp, "20240102T030405Z");
  EXPECT_EQ(n.seq, 12u);
  ASSERT_TRUE(parseRecordName("demo-20240102T030405Z.phrec", n));
  EXPECT_EQ(n.patient, "demo");
  EXPECT_EQ(n.seq, 0u);
  EXPECT_EQ(recordFileName(n), "demo-20240102T030405Z.phrec");
  EXPECT_EQ(recordFileName({"p-7", "20240102T030405Z", 3}), "p-7-20240102T030405Z-3.phrec");
  for (const char* bad : {"demo.phrec", "demo-20240102T030405Z.html", "-20240102T030405Z.phrec",
                          "demo-2024010T030405Z.phrec", "demo-20240102T030405Z-0.phrec", "demo-20240102T030405Z-.phrec",
                          "demo20240102T030405Z.phrec"}) {
    EXPECT_FALSE(parseRecordName(bad, n)) << bad;
  }
  EXPECT_EQ(recordStamp(0), "19700101T000000Z");
}

// Issue: profile `demo` got demo-001's record as its previous record, and `recordings --patient demo` listed
// demo-001's (a prefix match).
TEST(PatientRecords, ArePatientsOwnOnlyNeverAnotherPatientsWhoseIdStartsTheSame) {
  TempDir d;
  d.touch("demo-001-20240101T000000Z.phrec");
  d.touch("demo_x-20240101T000001Z.phrec");
  d.touch("demo-20230101T000000Z.phrec");
  d.touch("demo-20230101T000000Z.html");
  d.touch("notes.txt");
  EXPECT_EQ(patientRecords(d.path, "demo"), std::vector<std::string>{"demo-20230101T000000Z.phrec"});
  EXPECT_EQ(patientRecords(d.path, "demo-001"), std::vector<std::string>{"demo-001-20240101T000000Z.phrec"});
  EXPECT_EQ(newestRecord(d.path, "demo"), d.path + "/demo-20230101T000000Z.phrec");
  EXPECT_EQ(newestRecord(d.path, "nobody"), "");
  EXPECT_EQ(newestRecord(d.path + "/missing", "demo"), "");
}

// Issue: of several records made in the same second, previous_record picked the oldest.
TEST(PatientRecords, TheNewestOfOneSecondIsItsHighestSequenceNumber) {
  TempDir d;
  for (const char* f : {"p-20240101T000000Z.phrec", "p-20240101T000000Z-1.phrec", "p-20240101T000000Z-2.phrec",
                        "p-20240101T000000Z-10.phrec", "p-20231231T235959Z-5.phrec"}) {
    d.touch(f);
  }
  EXPECT_EQ(patientRecords(d.path, "p"),
            (std::vector<std::string>{"p-20231231T235959Z-5.phrec", "p-20240101T000000Z.phrec",
                                      "p-20240101T000000Z-1.phrec", "p-20240101T000000Z-2.phrec",
                                      "p-20240101T000000Z-10.phrec"}));
  EXPECT_EQ(newestRecord(d.path, "p"), d.path + "/p-20240101T000000Z-10.phrec");
  // A new record in that second comes after all of them, even with a gap in the numbers.
  const std::time_t t = 1704067200;  // 2024-01-01T00:00:00Z
  EXPECT_EQ(recordFileName(nextRecordName(d.path, "p", t)), "p-20240101T000000Z-11.phrec");
  EXPECT_EQ(recordFileName(nextRecordName(d.path, "q", t)), "q-20240101T000000Z.phrec");
  EXPECT_EQ(recordFileName(nextRecordName(d.path, "p", t + 1)), "p-20240101T000001Z.phrec");
}
