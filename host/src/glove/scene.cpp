#include "phalanx/host/glove/scene.h"

#include <cmath>

namespace phalanx::host::glove {

namespace pg = phalanx::glove;

namespace {

constexpr double kDeg = pg::kPi<double> / 180.0;

double dot(const Vec3d& a, const Vec3d& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

bool finite3(const Vec3d& v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }

/// H_R_O · (x, y, 0): a planar vector of {O} expressed in {H}.
Vec3d planarToHand(const Mat3d& R, double x, double y) {
  return {R[0][0] * x + R[0][1] * y, R[1][0] * x + R[1][1] * y, R[2][0] * x + R[2][1] * y};
}

/// Signed distance (m, negative inside) of point p to the object's surface and the outward unit normal.
double signedDistance(const VirtualObject& o, const Vec3d& p, Vec3d& n) {
  if (o.kind == ObjectKind::kPlane) {
    n = o.H_n;
    return dot(n, {p[0] - o.H_p_m[0], p[1] - o.H_p_m[1], p[2] - o.H_p_m[2]});
  }
  const Vec3d d{p[0] - o.H_p_m[0], p[1] - o.H_p_m[1], p[2] - o.H_p_m[2]};
  const double r = std::sqrt(dot(d, d));
  if (r > 1e-12) {
    n = {d[0] / r, d[1] / r, d[2] / r};
  } else {
    n = {0.0, 1.0, 0.0};  // exactly at the centre: any direction is a valid normal; push dorsally
  }
  return r - o.radius_m;
}

void resetOutput(FingerOutput& out, FingerStatus status) {
  out = FingerOutput{};
  out.status = status;
}

}  // namespace

HandModel defaultHandModel(Handedness side) {
  HandModel h{};
  h.side = side;
  for (std::size_t i = 0; i < kNumFingers; ++i) {
    h.fingers[i] = pg::defaultModel<double>(static_cast<FingerId>(i));
  }
  // Left hand, {H} at the middle MCP joint (docs/glove-model.md §"Hand model"). MCP joint centres of a
  // 197 mm hand: ≈ 19 mm apart across the knuckles (hand breadth ≈ 88 mm minus soft tissue and bone), the
  // middle knuckle the most distal, index 3 mm, ring 4 mm and little 14 mm proximal of it. Fingers fan out
  // slightly (adducted rest posture). The thumb chain starts at the CMC joint, ≈ 62 mm proximal, 28 mm
  // radial and 12 mm palmar of the middle MCP, its metacarpal pointing 40° radially and pronated 70° so that
  // it flexes across the palm.
  h.mounts[static_cast<std::size_t>(FingerId::kThumb)] = {{-0.062, -0.012, 0.028}, 40.0 * kDeg, 70.0 * kDeg};
  h.mounts[static_cast<std::size_t>(FingerId::kIndex)] = {{-0.003, 0.0, 0.019}, 6.0 * kDeg, 0.0};
  h.mounts[static_cast<std::size_t>(FingerId::kMiddle)] = {{0.0, 0.0, 0.0}, 0.0, 0.0};
  h.mounts[static_cast<std::size_t>(FingerId::kRing)] = {{-0.004, 0.0, -0.018}, -5.0 * kDeg, 0.0};
  h.mounts[static_cast<std::size_t>(FingerId::kLittle)] = {{-0.014, 0.0, -0.035}, -12.0 * kDeg, 0.0};
  if (side == Handedness::kRight) {
    for (FingerMount& m : h.mounts) {
      m.H_p_base_m[2] = -m.H_p_base_m[2];
      m.splay_rad = -m.splay_rad;
      m.roll_rad = -m.roll_rad;
    }
  }
  return h;
}

Mat3d fingerRotation(const FingerMount& mount) {
  const double cs = std::cos(mount.splay_rad), ss = std::sin(mount.splay_rad);
  const double cr = std::cos(mount.roll_rad), sr = std::sin(mount.roll_rad);
  const Vec3d x{cs, 0.0, ss};
  const Vec3d y{-sr * ss, cr, sr * cs};
  const Vec3d z{x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]};
  Mat3d R{};
  for (std::size_t r = 0; r < 3; ++r) R[r] = {x[r], y[r], z[r]};
  return R;
}

VirtualObject rigidBall(const Vec3d& H_center_m, double radius_m, ContactMaterial material) {
  VirtualObject o{};
  o.kind = ObjectKind::kBall;
  o.H_p_m = H_center_m;
  o.radius_m = radius_m;
  o.material = material;
  return o;
}

VirtualObject softBall(const Vec3d& H_center_m, double radius_m, ContactMaterial material) {
  return rigidBall(H_center_m, radius_m, material);
}

VirtualObject plane(const Vec3d& H_point_m, const Vec3d& H_normal, ContactMaterial material) {
  VirtualObject o{};
  o.kind = ObjectKind::kPlane;
  o.H_p_m = H_point_m;
  const double n = std::sqrt(dot(H_normal, H_normal));
  // A zero normal stays zero and is rejected by GloveScene::addObject().
  o.H_n = n > 0.0 ? Vec3d{H_normal[0] / n, H_normal[1] / n, H_normal[2] / n} : Vec3d{0.0, 0.0, 0.0};
  o.material = material;
  return o;
}

GloveScene::GloveScene(const HandModel& hand, const SceneConfig& config) : hand_(hand), config_(config) {
  for (std::size_t i = 0; i < kNumFingers; ++i) {
    H_R_O_[i] = fingerRotation(hand_.mounts[i]);
    capstan_[i] = pg::makeCapstanModel(hand_.fingers[i].mech, config_.mu, config_.gamma_c_rad);
  }
}

bool GloveScene::addObject(const VirtualObject& o) {
  if (object_count_ >= kMaxObjects) return false;
  if (!finite3(o.H_p_m) || !finite3(o.H_n) || !std::isfinite(o.radius_m)) return false;
  if (!std::isfinite(o.material.stiffness_N_per_m) || !std::isfinite(o.material.damping_N_s_per_m)) return false;
  if (o.material.stiffness_N_per_m < 0.0 || o.material.damping_N_s_per_m < 0.0) return false;
  if (o.kind == ObjectKind::kBall && !(o.radius_m > 0.0)) return false;
  if (o.kind == ObjectKind::kPlane && std::fabs(dot(o.H_n, o.H_n) - 1.0) > 1e-9) return false;
  objects_[object_count_++] = o;
  return true;
}

void GloveScene::render(const RenderInput& in, RenderOutput& out) {
  for (std::size_t i = 0; i < kNumFingers; ++i) renderFinger(i, in[i], out[i]);
}

void GloveScene::renderFinger(std::size_t i, const FingerInput& in, FingerOutput& out) {
  const pg::Model<double>& model = hand_.fingers[i];
  pg::Data<double>& d = data_[i];
  if (!finite3(in.alpha_rad)) {
    d = pg::Data<double>{};
    resetOutput(out, FingerStatus::kNonFiniteAngle);
    return;
  }
  if (!finite3(in.alpha_dot_rad_per_s)) {
    d = pg::Data<double>{};
    resetOutput(out, FingerStatus::kNonFiniteRate);
    return;
  }
  const pg::Status ks = pg::computeFromAlpha(model, in.alpha_rad, d);
  if (!pg::isUsable(ks)) {
    resetOutput(out, FingerStatus::kUnreachable);
    out.near_singular = d.alpha_near_singular;
    return;
  }
  resetOutput(out, FingerStatus::kOk);
  out.reach_clamped = ks == pg::Status::kReachClamped;
  out.near_singular = d.alpha_near_singular;
  out.theta_rad = d.theta_rad;

  // Fingertip pose and velocity: u from α, u̇ = J_α^u α̇ (eq 9–10), placed in {H}.
  const Mat3d& R = H_R_O_[i];
  const FingerMount& mount = hand_.mounts[i];
  const Vec3d O_u_dot = pg::mul(d.J_alpha_u, in.alpha_dot_rad_per_s);
  const Vec3d p_local = planarToHand(R, d.O_u_tip[0], d.O_u_tip[1]);
  out.H_p_tip_m = {mount.H_p_base_m[0] + p_local[0], mount.H_p_base_m[1] + p_local[1],
                   mount.H_p_base_m[2] + p_local[2]};
  out.H_v_tip_m_per_s = planarToHand(R, O_u_dot[0], O_u_dot[1]);

  // Contact forces, eq 1 per object along its normal, never pulling; summed, then clamped in magnitude.
  Vec3d F{0.0, 0.0, 0.0};
  double deepest = 0.0;
  for (std::size_t k = 0; k < object_count_; ++k) {
    const VirtualObject& o = objects_[k];
    Vec3d n{};
    const double sd = signedDistance(o, out.H_p_tip_m, n) - config_.tip_radius_m;
    if (!(sd < 0.0)) continue;
    const double x = -sd;
    const double x_dot = -dot(n, out.H_v_tip_m_per_s);
    const double f = renderedStiffness(k) * x + o.material.damping_N_s_per_m * x_dot;
    if (x > deepest) {
      deepest = x;
      out.contact_object = static_cast<int>(k);
      out.penetration_m = x;
      out.penetration_rate_m_per_s = x_dot;
    }
    out.in_contact = true;
    if (f > 0.0) {
      for (std::size_t c = 0; c < 3; ++c) F[c] += f * n[c];
    }
  }
  double f_mag = std::sqrt(dot(F, F));
  if (f_mag > config_.max_force_N) {
    const double s = config_.max_force_N / f_mag;
    for (double& c : F) c *= s;
    f_mag = config_.max_force_N;
    out.force_limited = true;
  }
  out.H_F_tip_N = F;
  out.normal_force_N = f_mag;

  // Setpoint: component along the pad normal (local y of link 3 at φ), the axis of the strain gauge.
  const double phi = d.O_u_tip[2];
  const Vec3d O_n_pad = pg::padNormal(phi);
  const Vec3d H_n_pad = planarToHand(R, O_n_pad[0], O_n_pad[1]);
  const double f_pad = dot(F, H_n_pad);
  out.force_setpoint_N = f_pad;

  // Mechanism joint torques that produce the commanded pad force, τ_α = (J_α^u)ᵀ F_pad (eq 18).
  out.tau_alpha_Nm = pg::mechanismTorqueFromWrench(
      d.J_alpha_u, Vec3d{f_pad * O_n_pad[0], f_pad * O_n_pad[1], 0.0});

  // Tendon feed-forward with capstan friction (eq 15–16). The release tendon carries a positive (extending)
  // pad force and shortens when the fingertip moves along +n_pad; the grasp tendon the opposite.
  out.tendon = f_pad >= 0.0 ? pg::Tendon::kRelease : pg::Tendon::kGrasp;
  out.tip_tension_N = std::fabs(f_pad) * config_.tendon_tension_per_pad_force;
  const double v_pad = O_n_pad[0] * O_u_dot[0] + O_n_pad[1] * O_u_dot[1];
  if (std::fabs(v_pad) < config_.slide_deadband_m_per_s) {
    out.spool_tension_N = out.tip_tension_N;
  } else {
    const bool shortening = (f_pad >= 0.0) == (v_pad > 0.0);
    const pg::Sliding sliding = shortening ? pg::Sliding::kTowardSpool : pg::Sliding::kTowardTip;
    pg::spoolTensionFor(capstan_[i], out.tendon, sliding, d.alpha_rad, out.tip_tension_N, out.spool_tension_N);
  }
}

bool GloveScene::setStiffnessLimit(double k_max_N_per_m) {
  if (!std::isfinite(k_max_N_per_m) || k_max_N_per_m < 0.0) return false;
  stiffness_limit_N_per_m_ = k_max_N_per_m;
  return true;
}

double GloveScene::renderedStiffness(std::size_t i) const {
  const double k = objects_[i].material.stiffness_N_per_m;
  return stiffness_limit_N_per_m_ > 0.0 ? std::fmin(k, stiffness_limit_N_per_m_) : k;
}

void loadDemoScene(GloveScene& scene, DemoScene which) {
  // Contact is rendered at the fingertips only (the phalanges pass through objects), so the ball must meet all five
  // fingertip pads, each with the pad facing it: a 90 mm ball resting against the palm, placed by a search for the
  // largest worst-finger pad-normal share of the contact force (0.64, the little finger). docs/glove-model.md.
  const Vec3d ball_center_m{-0.004, -0.060, -0.008};
  const double radius_m = 0.045;
  scene.clearObjects();
  switch (which) {
    case DemoScene::kRigidBall:
      scene.addObject(rigidBall(ball_center_m, radius_m));
      break;
    case DemoScene::kSoftBall:
      scene.addObject(softBall(ball_center_m, radius_m));
      break;
    case DemoScene::kWall:
      scene.addObject(plane({0.0, -0.040, 0.0}, {0.0, 1.0, 0.0}));
      break;
    case DemoScene::kNone:
    default:
      break;
  }
}

}  // namespace phalanx::host::glove
