#pragma once
/// Reads a `.phrec` session record, tolerating a torn tail (the daemon killed mid-write) and damaged records
/// (skipped by re-synchronising on the next sync word; both are counted, never silently hidden).
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/record/output_file.h"
#include "phalanx/host/record/record_format.h"

namespace phalanx::host::therapy {
struct KinematicParams;
}

namespace phalanx::host::record {

/// The patient's kinematic parameters a record's header carries ("kinematics"), as the report reads them.
therapy::KinematicParams kinematicsFromHeader(const nlohmann::json& header);

struct SessionRecord {
  nlohmann::json header;                 ///< null when the header record is missing/damaged
  std::vector<CycleRecord> cycles;
  std::vector<nlohmann::json> events;
  nlohmann::json footer;                 ///< null when the session did not end cleanly
  uint64_t bytes_total = 0;
  uint64_t bytes_skipped = 0;            ///< damaged or torn bytes (not part of a valid record)
  uint64_t bad_records = 0;              ///< framing/CRC failures in the middle of the file
  bool torn_tail = false;                ///< the file ends inside a record
  std::string source;                    ///< the file readRecord read ("" from parseRecord)
  FileId source_id;                      ///< its device + inode: exports never overwrite it
  bool complete() const { return !footer.is_null(); }
  /// Index of a channel name in the header's aux list, −1 if absent.
  int auxIndex(const std::string& name) const;
};

/// Reads the whole file. Returns "" or an error (cannot open; "not a record: …" for anything but a regular file,
/// e.g. /dev/zero or a FIFO; not a Phalanx record). Memory is bounded by the file's size (read once, up to the size
/// fstat gave). progress(done, total) is called every few megabytes when given.
std::string readRecord(const std::string& path, SessionRecord& out,
                       const std::function<void(uint64_t, uint64_t)>& progress = nullptr);

/// Same from bytes in memory.
std::string parseRecord(const std::vector<uint8_t>& data, SessionRecord& out,
                        const std::function<void(uint64_t, uint64_t)>& progress = nullptr);

/// CSV with one row per cycle: t_s, host_ns, device_time_us, seqs, modes, faults, samples by channel name
/// (mechanism angles in rad, …), setpoints, aux, then each joint's flexion in degrees (<joint>_flexion_deg, empty
/// when not measured). Written to a temporary file renamed into place when complete, so a failed export leaves an
/// existing csv_path untouched; refused when csv_path is the record's own file (rec.source_id: the same path, a
/// symlink or a hard link to it). Returns "" or an error.
std::string exportCsv(const SessionRecord& rec, const std::string& csv_path,
                      const std::function<void(uint64_t, uint64_t)>& progress = nullptr);

}  // namespace phalanx::host::record
