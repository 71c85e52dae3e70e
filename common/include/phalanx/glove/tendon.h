#pragma once
/// Tendon transmission of one glove finger, one definition shared by the simulated plant's design constants
/// and the firmware's feed-forward. 000 §3.4 models the tendon pair's action on the fingertip as a force normal
/// to the pad only (τ_i = a_2i f_y, eq 18–19): the net tendon tension T reaches the pad as c·T along n(φ).
/// The tendon path then changes with the pad-normal motion of the fingertip, q̇ = c·n(φ)·u̇ = r(α)·α̇, i.e.
/// pose-dependent effective moment arms r(α) = c·(J_α^u(α))ᵀ n(φ) with φ = α1 + α2 + α3 (eq 5).
/// Freestanding, templated on the scalar like kinematics.h.
#include "phalanx/glove/kinematics.h"

namespace phalanx::glove {

template <class T>
struct TendonDesign {
  T pad_transmission = T(0.3);  ///< c: pad-normal force per N of net tendon tension at the tip (docs/glove-plant.md)
  /// θ_ref: the mid-grasp finger pose at which the worm's passive holding force (35 N, 000 §2.2) is specified.
  Vec3<T> ref_pose_deg = {T(-45), T(-65), T(-45)};
};

/// Effective moment arms r(α) (m): tendon path rate per mechanism joint rate at pose α.
/// From the chained sines and cosines of α (thetaTrig(α), or the firmware's own, control/sincos.h).
template <class T>
inline Vec3<T> tendonMomentArms(const MechanismGeometry<T>& mech, const ThetaTrig<T>& alpha_trig, T pad_transmission) {
  const Vec3<T> n = {-alpha_trig.s123, alpha_trig.c123, T(0)};  // padNormal(φ), φ = α1 + α2 + α3
  Vec3<T> r = mulTransposed(jacobianAlphaU(mech, alpha_trig), n);
  for (T& v : r) v *= pad_transmission;
  return r;
}

template <class T>
inline Vec3<T> tendonMomentArms(const MechanismGeometry<T>& mech, const Vec3<T>& alpha_rad, T pad_transmission) {
  return tendonMomentArms(mech, thetaTrig(alpha_rad), pad_transmission);
}

}  // namespace phalanx::glove
