#pragma once
/// Fingerprint of a device's compile-time geometry, so that the host can refuse to run a model whose lengths
/// differ from the ones the firmware was built with (docs/design-tools.md §"Geometry files").
///
/// Every length is rounded to 0.01 mm and every angle to 0.01°, then hashed with 32-bit FNV-1a folded to 24 bits:
/// the result is an integer < 2^24, exactly representable in the float of a ParamValue. The arithmetic is single
/// precision on both sides (the host converts its double geometry to float first), so firmware and host compute
/// the same value. Freestanding: no heap, no exceptions, float only.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <initializer_list>

#include "phalanx/glove/kinematics.h"
#include "phalanx/pen/kinematics.h"

namespace phalanx {

class GeometryFingerprint {
 public:
  void addLength(float metres) { add(static_cast<std::int32_t>(std::lround(metres * 1e5f))); }
  void addAngle(float rad) { add(static_cast<std::int32_t>(std::lround(rad * (18000.0f / 3.14159265f)))); }
  /// 24-bit value (as a float it is exact).
  std::uint32_t value() const { return (h_ >> 24) ^ (h_ & 0xFFFFFFu); }

 private:
  void add(std::int32_t v) {
    const auto u = static_cast<std::uint32_t>(v);
    for (int i = 0; i < 4; ++i) {
      h_ ^= (u >> (8 * i)) & 0xFFu;
      h_ *= 16777619u;
    }
  }
  std::uint32_t h_ = 2166136261u;
};

/// Twin-Pantograph: l1, l2, l3, l4, l6, home depth.
template <class T>
std::uint32_t geometryFingerprint(const pen::Geometry<T>& g) {
  GeometryFingerprint f;
  for (T v : {g.l1_m, g.l2_m, g.l3_m, g.l4_m, g.l6_m, g.home_z_m}) f.addLength(static_cast<float>(v));
  return f.value();
}

/// One glove finger's mechanism: link lengths, l_p, B0, and the α limits (the firmware's joint windows).
template <class T>
std::uint32_t geometryFingerprint(const glove::MechanismGeometry<T>& m) {
  GeometryFingerprint f;
  for (T v : {m.l1_m, m.l2_m, m.l3_m, m.l_p_m, m.x_B0_m, m.y_B0_m}) f.addLength(static_cast<float>(v));
  for (std::size_t i = 0; i < 3; ++i) {
    f.addAngle(static_cast<float>(m.alpha_min_rad[i]));
    f.addAngle(static_cast<float>(m.alpha_max_rad[i]));
  }
  return f.value();
}

}  // namespace phalanx
