#pragma once
/// The name the host's messages on stderr begin with: "phalanxd" in the daemon, "phalanx" when the same session
/// runs under `phalanx run` (a user of `phalanx run` should not read errors signed by another program).
namespace phalanx::host {

inline const char*& programNameSlot() {
  static const char* name = "phalanxd";
  return name;
}
/// Set once by main before anything else runs.
inline void setProgramName(const char* name) { programNameSlot() = name; }
inline const char* programName() { return programNameSlot(); }

}  // namespace phalanx::host
