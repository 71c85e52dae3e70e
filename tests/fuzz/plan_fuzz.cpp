// libFuzzer target: bench plans (`phalanx bench run PLAN.yaml`, benchrun/plan.cpp).
#include "fuzz_util.h"
#include "phalanx/host/benchrun/runner.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  phalanx::host::benchrun::Plan plan;
  const std::string err = phalanx::host::benchrun::loadPlanText(phalanx::fuzz::text(data, size), "fuzz.yaml", plan);
  if (err.empty() && plan.steps.empty()) __builtin_trap();  // a plan with nothing to run was accepted
  return 0;
}
