// libFuzzer target: therapy patient profiles (therapy/profile.cpp).
#include "fuzz_util.h"
#include "phalanx/host/therapy/profile.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  phalanx::host::therapy::Profile p;
  const std::string err = phalanx::host::therapy::loadProfileText(phalanx::fuzz::text(data, size), "fuzz.yaml", p);
  if (err.empty() && p.patient.empty()) __builtin_trap();  // accepted without a patient id
  return 0;
}
