#include "phalanx/host/therapy/records_dir.h"

#include <dirent.h>

#include <algorithm>
#include <cctype>
#include <utility>

namespace phalanx::host::therapy {
namespace {

constexpr std::size_t kStampLength = 16;  // YYYYMMDDTHHMMSSZ
const std::string kSuffix = ".phrec";

bool isStamp(const std::string& s) {
  if (s.size() != kStampLength || s[8] != 'T' || s[15] != 'Z') return false;
  for (std::size_t i = 0; i < kStampLength; ++i) {
    if (i != 8 && i != 15 && std::isdigit(static_cast<unsigned char>(s[i])) == 0) return false;
  }
  return true;
}

bool isCount(const std::string& s) {
  return !s.empty() && s.size() <= 6 && s[0] != '0' &&
         std::all_of(s.begin(), s.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; });
}

std::vector<std::string> recordFiles(const std::string& dir) {
  std::vector<std::string> out;
  DIR* d = ::opendir(dir.c_str());
  if (d == nullptr) return out;
  while (const dirent* e = ::readdir(d)) out.emplace_back(e->d_name);
  ::closedir(d);
  return out;
}

}  // namespace

bool parseRecordName(const std::string& file, RecordName& out) {
  if (file.size() <= kSuffix.size() || file.compare(file.size() - kSuffix.size(), kSuffix.size(), kSuffix) != 0) {
    return false;
  }
  std::string stem = file.substr(0, file.size() - kSuffix.size());
  RecordName n;
  // "<patient>-<stamp>-<n>": the stamp never ends in a digit, so a trailing "-<digits>" is the sequence number.
  const auto dash = stem.rfind('-');
  if (dash != std::string::npos && isCount(stem.substr(dash + 1))) {
    n.seq = static_cast<unsigned>(std::stoul(stem.substr(dash + 1)));
    stem.erase(dash);
  }
  if (stem.size() < kStampLength + 2 || stem[stem.size() - kStampLength - 1] != '-') return false;
  n.stamp = stem.substr(stem.size() - kStampLength);
  n.patient = stem.substr(0, stem.size() - kStampLength - 1);
  if (!isStamp(n.stamp) || n.patient.empty()) return false;
  out = std::move(n);
  return true;
}

std::string recordFileName(const RecordName& name) {
  return name.patient + "-" + name.stamp + (name.seq == 0 ? "" : "-" + std::to_string(name.seq)) + kSuffix;
}

std::string recordStamp(std::time_t t) {
  char stamp[32];
  std::tm tm{};
  ::gmtime_r(&t, &tm);
  std::strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &tm);
  return stamp;
}

std::vector<std::string> patientRecords(const std::string& dir, const std::string& patient) {
  std::vector<std::pair<RecordName, std::string>> found;
  for (const std::string& f : recordFiles(dir)) {
    RecordName n;
    if (parseRecordName(f, n) && n.patient == patient) found.emplace_back(n, f);
  }
  std::sort(found.begin(), found.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<std::string> out;
  for (auto& [n, f] : found) out.push_back(std::move(f));
  return out;
}

std::vector<std::string> recordPatients(const std::string& dir) {
  std::vector<std::string> out;
  for (const std::string& f : recordFiles(dir)) {
    RecordName n;
    if (parseRecordName(f, n) && std::find(out.begin(), out.end(), n.patient) == out.end()) out.push_back(n.patient);
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::string newestRecord(const std::string& dir, const std::string& patient) {
  const auto records = patientRecords(dir, patient);
  return records.empty() ? std::string() : dir + "/" + records.back();
}

RecordName nextRecordName(const std::string& dir, const std::string& patient, std::time_t when) {
  RecordName next{patient, recordStamp(when), 0};
  for (const std::string& f : recordFiles(dir)) {
    RecordName n;
    if (parseRecordName(f, n) && n.patient == patient && n.stamp == next.stamp) next.seq = std::max(next.seq, n.seq + 1);
  }
  return next;
}

}  // namespace phalanx::host::therapy
