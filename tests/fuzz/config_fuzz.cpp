// libFuzzer target: phalanxd's YAML configuration (config.cpp, yaml_keys.cpp and the option loaders it calls:
// Modbus, client channel, GPIO, dashboard). Any text must give "" or an error naming the problem, and a refused
// file must leave the options untouched.
#include "fuzz_util.h"
#include "phalanx/host/config.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  phalanx::host::RunOptions opt;
  const phalanx::host::RunOptions before = opt;
  const std::string err = phalanx::host::loadConfigText(phalanx::fuzz::text(data, size), "fuzz.yaml", opt);
  if (!err.empty() && (opt.device != before.device || opt.seconds != before.seconds || opt.rate_hz != before.rate_hz)) {
    __builtin_trap();  // a refused configuration changed the options
  }
  return 0;
}
