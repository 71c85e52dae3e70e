#pragma once
/// The records directory of the control API: one `.phrec` per session, named
/// `<patient>-<YYYYMMDDTHHMMSSZ>[-<n>].phrec` (UTC start second; n = 1, 2, … for further sessions of the same
/// patient in the same second; `anonymous-…` for a session without a profile). Records are matched to a patient
/// by parsing the whole name, never by a prefix: `demo-001-….phrec` is not a record of patient `demo`.
#include <ctime>
#include <string>
#include <vector>

namespace phalanx::host::therapy {

/// The patient part of the records of sessions without a profile (a reserved patient id).
inline constexpr const char* kAnonymousPatient = "anonymous";

struct RecordName {
  std::string patient;
  std::string stamp;  ///< YYYYMMDDTHHMMSSZ
  unsigned seq = 0;   ///< 0: the first record of that second
  /// Order of the sessions of one patient: start second, then sequence number.
  bool operator<(const RecordName& o) const { return stamp != o.stamp ? stamp < o.stamp : seq < o.seq; }
};

/// false when `file` (a name, no directory) is not a record name.
bool parseRecordName(const std::string& file, RecordName& out);
std::string recordFileName(const RecordName& name);
/// "YYYYMMDDTHHMMSSZ" of t (UTC).
std::string recordStamp(std::time_t t);

/// The records of exactly this patient in dir, oldest first (see RecordName::operator<); file names only.
std::vector<std::string> patientRecords(const std::string& dir, const std::string& patient);
/// Every patient with a record in dir, sorted (file names parsed as above).
std::vector<std::string> recordPatients(const std::string& dir);
/// The newest of them as dir/file, "" when there is none.
std::string newestRecord(const std::string& dir, const std::string& patient);
/// The name a new record of this patient started at `when` gets: the next sequence number after the records
/// of that second already in dir.
RecordName nextRecordName(const std::string& dir, const std::string& patient, std::time_t when);

}  // namespace phalanx::host::therapy
