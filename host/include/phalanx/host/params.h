#pragma once
/// Device parameters by name, and the settings backup (docs/params.md): what `phalanx param` lists, reads, sets,
/// saves into the device's flash, backs up to YAML and restores from it. The ids and which of them the device
/// persists come from the firmware headers (phalanx/apps/*.h, core_param in messages.h); the names are here.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "phalanx/protocol/devices.h"

namespace phalanx::host::params {

enum class Access : uint8_t {
  kReadOnly,  ///< read: an identity, a fingerprint, a status
  kSettable,  ///< read and write (refused by the device while its outputs are active)
  kAction,    ///< write 1 to start something (a tare); never saved nor restored
};

struct ParamInfo {
  uint16_t id = 0;
  std::string name;
  Access access = Access::kReadOnly;
  bool persisted = false;  ///< kept in the device's flash by `param save` (and in a backup)
};

/// Every parameter a device type answers: the core's, then the device's. `persisted` follows the settings layout
/// version the firmware writes (core parameter settings_layout); 0 or a version this build does not know: the
/// newest.
std::vector<ParamInfo> known(protocol::DeviceType type, uint16_t layout_version = 0);
/// A parameter by name or by id (0x0100 or 256). nullptr and `error` naming what was wrong when it is unknown.
const ParamInfo* lookup(const std::vector<ParamInfo>& table, const std::string& key, std::string& error);

/// A settings backup: the device's persisted parameters by name.
struct Backup {
  std::string device_type;  ///< protocol::DeviceLayout::name
  std::string build_id;     ///< the firmware's build id (8 hex digits) when it was taken: for the record only
  std::map<std::string, float> values;
};

std::string toYaml(const Backup& b);
/// Read and check a backup for this device type and settings layout: every key known, every name a parameter
/// that layout persists, every value finite. "" or the problem (naming the file and what is wrong); nothing
/// partial is returned on a problem.
std::string readBackup(const std::string& path, protocol::DeviceType type, Backup& out, uint16_t layout_version = 0);

/// One difference between the device and a backup.
struct Difference {
  std::string name;
  bool on_device = true, in_file = true;
  float device_value = 0.0f, file_value = 0.0f;
};
/// Persisted parameters whose values differ (exactly: a backup carries the device's f32 values with 9 digits).
std::vector<Difference> diff(const std::map<std::string, float>& device, const std::map<std::string, float>& file);

}  // namespace phalanx::host::params
