#pragma once
/// RML glove tendon transmission: capstan friction of the grasp/release tendons over the mechanism pulleys
/// (Ma & Ben-Tzvi 2015, seeds/000 §3.3 eq 15–16, §4.2).
///
/// Header-only, freestanding C++17, templated on the scalar (double host / float MCU), no heap, no exceptions.
///
/// Routing model assumed (the paper gives the principle, not the pulley layout; docs/glove-model.md):
///  - Each tendon leaves the actuator spool, passes the fixed secondary pulleys on the support pad (a
///    constant total wrap γ_c), then one guide pulley per mechanism joint (B0, B1, B2), and ends at the tip
///    of link 3.
///  - At joint i the tendon wraps the joint pulley by an angle that changes 1:1 with α_i and is smallest at
///    one end of the joint's range, so Δγ_i ∈ [0, α_i,var] — the paper's statement that the maximum Δγ of a
///    joint is its range α_i,var (eq 14, §3.3).
///  - Grasp tendon (tension closes the mechanism, i.e. drives every α_i negative): it runs on the inner side
///    of each joint pulley, so its wrap grows as the joint OPENS: Δγ_i = α_i − α_i,min.
///    Release tendon (opens the mechanism): outer side, wrap grows as the joint CLOSES: Δγ_i = α_i,max − α_i.
///  - γ = γ_c + Σ_i Δγ_i (eq 16); α outside [α_min, α_max] is clamped into it.
///  - Capstan equation F1/F2 = e^{μγ} (eq 15), F1 on the side the tendon slides towards (the pulling side).
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "phalanx/glove/kinematics.h"

namespace phalanx::glove {

/// Tendon/pulley kinetic friction coefficient, lubricated (§4.2, least-squares fit for wraps ≥ 90°).
template <class T>
inline constexpr T kMuLubricated = T(0.0530);
/// Tendon/pulley kinetic friction coefficient, dry / non-lubricated (§4.2).
template <class T>
inline constexpr T kMuDry = T(0.0631);
/// Default constant wrap γ_c (rad): 90°, the smallest wrap the paper says the glove ever has (§4.2: eq 15
/// holds "when the wrap angle is above 90 deg, which will always be satisfied for the glove mechanism").
/// A placeholder until measured on the device with the §4.2 load-cell method.
template <class T>
inline constexpr T kGammaConstDefault_rad = kPi<T> / T(2);

enum class Tendon : std::uint8_t {
  kGrasp = 0,    ///< "red" tendon: tension closes the mechanism/finger (flexion)
  kRelease = 1,  ///< "blue" tendon: tension opens the mechanism/finger (extension)
};

/// Direction the tendon slides over the pulleys; decides which end is F1 in eq 15.
enum class Sliding : std::uint8_t {
  kTowardSpool = 0,  ///< spool reels the tendon in (actuator does work): F_spool = e^{μγ} F_tip
  kTowardTip = 1,    ///< the finger pulls the tendon out against the spool: F_tip = e^{μγ} F_spool
};

enum class CapstanStatus : std::uint8_t {
  kOk = 0,
  kNonFiniteInput = 1,   ///< NaN/Inf tension or angle: output set to 0
  kNegativeTension = 2,  ///< a tendon cannot push: negative input tension, output set to 0
};

template <class T>
struct CapstanModel {
  T mu = kMuLubricated<T>;                       ///< friction coefficient (–)
  T gamma_c_rad = kGammaConstDefault_rad<T>;     ///< constant wrap component γ_c (eq 16)
  Vec3<T> alpha_min_rad{};                       ///< joint range bounding Δγ (Table 3 / MechanismGeometry)
  Vec3<T> alpha_max_rad{};
};

/// Capstan model for a mechanism, using its α range (MechanismGeometry::alpha_min/max_rad).
template <class T>
inline CapstanModel<T> makeCapstanModel(const MechanismGeometry<T>& mech, T mu = kMuLubricated<T>,
                                        T gamma_c_rad = kGammaConstDefault_rad<T>) {
  CapstanModel<T> c{};
  c.mu = mu;
  c.gamma_c_rad = gamma_c_rad;
  c.alpha_min_rad = mech.alpha_min_rad;
  c.alpha_max_rad = mech.alpha_max_rad;
  return c;
}

/// Eq 15: F1/F2 = e^{μγ}.
template <class T>
inline T capstanRatio(T mu, T gamma_rad) {
  return std::exp(mu * gamma_rad);
}

/// Total wrap γ = γ_c + Σ Δγ_i (eq 16, rad) of `tendon` at mechanism angles α (rad), routing model above.
template <class T>
inline T wrapAngle_rad(const CapstanModel<T>& c, Tendon tendon, const Vec3<T>& alpha_rad) {
  T gamma = c.gamma_c_rad;
  for (std::size_t i = 0; i < 3; ++i) {
    const T a = clampTo(alpha_rad[i], c.alpha_min_rad[i], c.alpha_max_rad[i]);
    gamma += tendon == Tendon::kGrasp ? a - c.alpha_min_rad[i] : c.alpha_max_rad[i] - a;
  }
  return gamma;
}

/// Tendon tension at the link-3 end (N) from the spool-side tension (N), eq 15–16.
template <class T>
inline CapstanStatus tipTension(const CapstanModel<T>& c, Tendon tendon, Sliding sliding,
                                const Vec3<T>& alpha_rad, T spool_tension_N, T& tip_tension_N) {
  tip_tension_N = T(0);
  if (!std::isfinite(spool_tension_N) || !allFinite(alpha_rad)) return CapstanStatus::kNonFiniteInput;
  if (spool_tension_N < T(0)) return CapstanStatus::kNegativeTension;
  const T ratio = capstanRatio(c.mu, wrapAngle_rad(c, tendon, alpha_rad));
  tip_tension_N = sliding == Sliding::kTowardSpool ? spool_tension_N / ratio : spool_tension_N * ratio;
  return CapstanStatus::kOk;
}

/// Inverse of tipTension(): the spool-side tension (N) that gives `tip_tension_N` at link 3 — the host's
/// tendon-tension (friction) compensation.
template <class T>
inline CapstanStatus spoolTensionFor(const CapstanModel<T>& c, Tendon tendon, Sliding sliding,
                                     const Vec3<T>& alpha_rad, T tip_tension_N, T& spool_tension_N) {
  spool_tension_N = T(0);
  if (!std::isfinite(tip_tension_N) || !allFinite(alpha_rad)) return CapstanStatus::kNonFiniteInput;
  if (tip_tension_N < T(0)) return CapstanStatus::kNegativeTension;
  const T ratio = capstanRatio(c.mu, wrapAngle_rad(c, tendon, alpha_rad));
  spool_tension_N = sliding == Sliding::kTowardSpool ? tip_tension_N * ratio : tip_tension_N / ratio;
  return CapstanStatus::kOk;
}

}  // namespace phalanx::glove
