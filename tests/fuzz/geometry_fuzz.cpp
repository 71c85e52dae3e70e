// libFuzzer target: geometry files of `phalanx design` (glove finger geometry, pen geometry), as phalanxd's
// glove.geometry and pen.geometry read them. Both parsers see every input.
#include <cmath>

#include "fuzz_util.h"
#include "phalanx/host/design/glove_design.h"
#include "phalanx/host/design/pen_geometry.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string yaml = phalanx::fuzz::text(data, size);
  phalanx::host::design::GloveModel glove{};
  if (phalanx::host::design::loadGloveGeometryText(yaml, "fuzz.yaml", glove).empty()) {
    if (!(glove.mech.l1_m > 0) || !(glove.finger.p1_m > 0)) __builtin_trap();  // accepted a non-positive length
  }
  phalanx::pen::Geometry<double> pen{};
  if (phalanx::host::design::loadPenGeometryText(yaml, "fuzz.yaml", pen).empty()) {
    if (!std::isfinite(pen.l1_m) || !(pen.l1_m > 0)) __builtin_trap();
  }
  return 0;
}
