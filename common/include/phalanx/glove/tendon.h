#pragma once
/// Tendon routing of one glove finger: the constant-radius pulley moment arms r_i of the antagonistic tendon
/// pair at the three mechanism joints. One definition shared by the simulated plant (which drives the
/// mechanism through them) and the firmware (whose feed-forward moves the spool with the finger through them).
/// Freestanding, templated on the scalar like kinematics.h.
#include "phalanx/glove/kinematics.h"

namespace phalanx::glove {

/// Design of the routing: r is chosen so that at the mid-grasp pose θ_ref the tendon's tip wrench
/// (J_α^u)^{-T} r T is a pure pad-normal force c_ref·T (000 §3.4 design intent, τ_i = a_2i f_y):
/// r = c_ref·(J_α^u(α_ref))ᵀ n(φ_ref).
template <class T>
struct TendonDesign {
  Vec3<T> ref_pose_deg = {T(-45), T(-65), T(-45)};  ///< θ_ref: mid-grasp finger pose
  T pad_transmission_ref = T(0.3);                  ///< c_ref: pad-normal force per N of tip tension at θ_ref
};

/// Moment arms r (m) for a finger model; false if θ_ref is not reachable by the mechanism.
template <class T>
inline bool tendonMomentArms(const Model<T>& model, const TendonDesign<T>& design, Vec3<T>& r_m) {
  Vec3<T> theta_ref{};
  for (std::size_t j = 0; j < 3; ++j) theta_ref[j] = degToRad(design.ref_pose_deg[j]);
  Vec3<T> alpha_ref{};
  if (!isUsable(alphaFromTheta(model, theta_ref, alpha_ref))) return false;
  const Mat3<T> Ja_ref = jacobianAlphaU(model.mech, alpha_ref);
  const Vec3<T> n_ref = padNormal(tipPoseFromTheta(model.finger, theta_ref)[2]);
  r_m = mulTransposed(Ja_ref, n_ref);
  for (T& r : r_m) r *= design.pad_transmission_ref;
  return true;
}

}  // namespace phalanx::glove
