#pragma once
/// SEA index-finger exoskeleton: kinematics and statics of the coupled finger–exoskeleton system
/// (Agarwal et al., IJRR 2015, seeds/001 §3.1, §4.2, §5.2, Appendix).
///
/// Header-only, freestanding C++17 (no heap, no exceptions, no iostream), templated on the scalar type
/// (`double` on the host and in the simulated plant, `float` possible on a microcontroller). Pinocchio style:
/// a const `Model<T>` (geometry) and a preallocated `Data<T>` workspace written by `computeFromSensors()`
/// (the paper's "forward kinematics": sensors → finger, used by the host estimator) and `computeFromFinger()`
/// (finger → exoskeleton + all five sensor readings, used by the simulated plant and for synthetic data).
///
/// Frames and conventions (docs/sea-model.md has the full reconstruction of Fig 5 from eq 3 and eq 19):
///  - {B}: planar frame at the actuated exoskeleton MCP joint B. x along the back of the hand pointing distally
///    (parallel to the metacarpal), y dorsal. Angles counter-clockwise, so finger FLEXION IS NEGATIVE.
///    A = (x_A, y_A) is the finger MCP joint axis in {B} (y_A < 0: A is palmar of B).
///  - MCP chain (eq 3): l_BC e^{iθ1} + l_CD e^{iθ2} + x3 e^{i(θ4−π)} = x_A + i y_A, with θ2 = θ4 − π/2
///    (link CD is perpendicular to the proximal phalanx; its slider D runs on the phalanx axis; this is the
///    orientation that reproduces the appendix entries J11, J21). θ1 = θ1r is the exo MCP sensor.
///  - PIP chain (four revolute joints C, E, F, H): links CE (L1) and EF (L2) of the exoskeleton, the middle
///    phalanx rest F-G-H (G = foot of F on the middle phalanx axis, |FG| = l_FG, |GH| = l_GH, so
///    l_FH = hypot(l_FG, l_GH), θ_HFG = atan2(l_GH, l_FG)). In the proximal-phalanx frame at H:
///      (x3 − l_AH) + i l_CD + l_CE e^{iθ5} − l_EF e^{i(θ5+θ6r)} = l_FH e^{i(θ8 + π/2 − θ_HFG)}
///    θ5: direction of C→E relative to the proximal phalanx (passive joint at C);
///    θ6r: interior angle at E from E→C to E→F, counter-clockwise, in (0, π) (exo PIP sensor, actuated);
///    θ8: finger PIP angle (middle relative to proximal phalanx). With these definitions the appendix's
///    J32 and J42 (eq 19) hold literally with a = θ_HFG + θ5 − θ8.
///    θ7r: the REDUNDANT sensor, at the passive joint F: direction of F→E relative to the middle rest's axis
///    G→F, θ7r = θ5 + θ6r − θ8 − π/2. (A sensor at C would see l_FG, l_GH only through l_FH = hypot(l_FG, l_GH),
///    so eq 12 could not separate them; at F it also sees θ_HFG. docs/sea-model.md §Redundant sensor.)
///  - DIP chain (3R + 1P, same structure as the MCP chain, parameters chosen — the paper gives none): in the
///    middle-phalanx frame at H, exo pivot K = (x_K, y_K) on the middle rest, link KL at angle θ_K (the DIP
///    chain sensor), link LM ⟂ distal phalanx, slider M at x_dip from the finger DIP joint I = (l_HI, 0).
///  - X = [x3 θ4 θ5 θ8]ᵀ, Θ_r = [θ1r θ6r]ᵀ (eq 4); J = ∂X/∂Θ_r, 4×2, J[row][col] (eq 5).
///  - Sensor channels (telemetry samples 0..4 of sea_finger): see `SensorIndex`.
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

namespace phalanx::sea {

template <class T>
inline constexpr T kPi = T(3.14159265358979323846);

template <class T>
constexpr T degToRad(T deg) {
  return deg * (kPi<T> / T(180));
}
template <class T>
constexpr T radToDeg(T rad) {
  return rad * (T(180) / kPi<T>);
}

/// Row-major matrices, M[row][col].
template <class T>
using Mat42 = std::array<std::array<T, 2>, 4>;
template <class T>
using Mat2 = std::array<std::array<T, 2>, 2>;
template <class T>
using Vec2 = std::array<T, 2>;

/// Result of a kinematic computation. Faults 1..15; from 16 "usable, with a caveat".
enum class Status : std::uint8_t {
  kOk = 0,
  kNonFiniteInput = 1,  ///< NaN/Inf input: outputs left at 0
  kSingular = 2,        ///< the Jacobian (or J_n) is numerically singular: J left at 0
  kLeastSquares = 16,   ///< a chain could not close exactly (parameter error): least-squares pose returned
};

/// True when the outputs of a call that returned `s` may be used.
constexpr bool isUsable(Status s) { return s == Status::kOk || s == Status::kLeastSquares; }

/// The five joint angle sensors (§3.4, Fig 4(a)), in telemetry order (sea_finger samples 0..4), rad.
enum SensorIndex : std::size_t {
  kSensorExoMcp = 0,     ///< θ1r at B: actuated exoskeleton MCP joint (SEA)
  kSensorExoPip = 1,     ///< θ6r at E: actuated exoskeleton PIP joint (SEA), interior angle in (0, π)
  kSensorRedundant = 2,  ///< θ7r at F: link FE relative to the middle rest (G→F); redundant, used by eq 12
  kSensorDip = 3,        ///< θ_K at K: DIP chain link KL relative to the middle phalanx
  kSensorAbduction = 4,  ///< passive MCP abduction–adduction joint (§3.4); not part of the planar model
};
inline constexpr std::size_t kNumSensors = 5;
template <class T>
using Sensors = std::array<T, kNumSensors>;

/// The seven subject-dependent parameters estimated by eq 12 (Table 4), metres.
template <class T>
struct SubjectParams {
  T x_A_m{};   ///< finger MCP joint A in {B}, x
  T y_A_m{};   ///< finger MCP joint A in {B}, y (negative: palmar of B)
  T l_BC_m{};  ///< exo MCP link BC
  T l_CD_m{};  ///< proximal rest link CD (⟂ proximal phalanx)
  T l_AH_m{};  ///< proximal phalanx, finger MCP A → finger PIP H
  T l_FG_m{};  ///< middle rest: height of pivot F over the middle phalanx axis
  T l_GH_m{};  ///< middle rest: distance from the PIP joint H along the middle phalanx to G
};
inline constexpr std::size_t kNumSubjectParams = 7;

/// Parameter vector P = [x_A y_A l_BC l_CD l_AH l_FG l_GH]ᵀ in the order of eq 12 / Table 4.
template <class T>
inline std::array<T, kNumSubjectParams> toArray(const SubjectParams<T>& p) {
  return {p.x_A_m, p.y_A_m, p.l_BC_m, p.l_CD_m, p.l_AH_m, p.l_FG_m, p.l_GH_m};
}
template <class T>
inline SubjectParams<T> fromArray(const std::array<T, kNumSubjectParams>& a) {
  return {a[0], a[1], a[2], a[3], a[4], a[5], a[6]};
}
/// Names in the same order (config keys).
inline constexpr std::array<const char*, kNumSubjectParams> kSubjectParamNames{
    "x_A_m", "y_A_m", "l_BC_m", "l_CD_m", "l_AH_m", "l_FG_m", "l_GH_m"};

/// Table 4, row P̂: the parameters the paper estimated for its subject (the default subject here).
template <class T>
constexpr SubjectParams<T> table4Estimate() {
  return {T(0.000), T(-0.036), T(0.042), T(0.035), T(0.040), T(0.029), T(0.029)};
}
/// Table 4, row P0: the paper's initial guess for the optimiser.
template <class T>
constexpr SubjectParams<T> table4Initial() {
  return {T(0.008), T(-0.030), T(0.047), T(0.025), T(0.047), T(0.018), T(0.015)};
}
/// Table 4, rows LB/UB: caliper-measured range for typical hand sizes. The paper prints y_A's LB = −0.029 and
/// UB = −0.039 (swapped; LB > UB); here lower = −0.039, upper = −0.029 (docs/sea-model.md).
template <class T>
constexpr SubjectParams<T> table4Lower() {
  return {T(-0.002), T(-0.039), T(0.040), T(0.024), T(0.038), T(0.016), T(0.014)};
}
template <class T>
constexpr SubjectParams<T> table4Upper() {
  return {T(0.010), T(-0.029), T(0.050), T(0.037), T(0.052), T(0.030), T(0.030)};
}

/// Exoskeleton and finger geometry NOT estimated by eq 12 (set from CAD / link-length screws and a ruler).
/// The paper does not print these; the defaults are chosen in docs/sea-model.md §Constants.
template <class T>
struct FixedGeometry {
  T l_CE_m{};  ///< exo link L1 (C → E)
  T l_EF_m{};  ///< exo link L2 (E → F)
  T l_HI_m{};  ///< middle phalanx, finger PIP H → finger DIP I
  T x_K_m{};   ///< DIP chain exo pivot K on the middle rest, along the middle phalanx from H
  T y_K_m{};   ///< … and dorsal of its axis
  T l_KL_m{};  ///< DIP chain exo link KL
  T l_LM_m{};  ///< distal rest link LM (⟂ distal phalanx)
};

/// Geometry + the finger workspace it was checked over + numerical guards.
template <class T>
struct Model {
  SubjectParams<T> subject{};
  FixedGeometry<T> fixed{};
  /// Finger workspace (rad) over which the default geometry is checked to be non-singular (tests); flexion < 0.
  Vec2<T> mcp_range_rad{};
  Vec2<T> pip_range_rad{};
  Vec2<T> dip_range_rad{};
  /// A slider length (x3 or x_dip) below this makes the chain's Jacobian singular (J21 ∝ 1/x3): 0.5 mm.
  T min_slider_m = T(0.0005);
  /// |det| of the PIP loop's 2×2 (m², ∝ sin of the angle C-F-H) below this is a dead point: 1e-7 m² ≈ 0.1° at
  /// |CF|·l_FH ≈ 0.04 m · 0.04 m.
  T min_pip_det_m2 = T(1e-7);
};

/// Default model: Table 4 P̂ for the subject + the fixed geometry of docs/sea-model.md.
template <class T>
inline Model<T> defaultModel() {
  Model<T> m{};
  m.subject = table4Estimate<T>();
  m.fixed.l_CE_m = T(0.050);
  m.fixed.l_EF_m = T(0.040);
  m.fixed.l_HI_m = T(0.025);
  m.fixed.x_K_m = T(0.015);
  m.fixed.y_K_m = T(0.015);
  m.fixed.l_KL_m = T(0.030);
  m.fixed.l_LM_m = T(0.012);
  m.mcp_range_rad = {degToRad(T(-60)), T(0)};
  m.pip_range_rad = {degToRad(T(-80)), T(0)};
  m.dip_range_rad = {degToRad(T(-60)), T(0)};
  return m;
}

/// |FH| of the middle rest (m).
template <class T>
inline T lengthFH(const SubjectParams<T>& p) {
  return std::hypot(p.l_FG_m, p.l_GH_m);
}
/// Angle H-F-G of the middle rest (rad).
template <class T>
inline T angleHFG(const SubjectParams<T>& p) {
  return std::atan2(p.l_GH_m, p.l_FG_m);
}

/// Finger joint angles (rad, flexion negative) and the passive abduction angle.
template <class T>
struct FingerAngles {
  T mcp_rad{};  ///< θ4
  T pip_rad{};  ///< θ8
  T dip_rad{};  ///< θ_dip
  T abduction_rad{};
};

/// Workspace of one cycle: the full configuration of the coupled system, the sensor readings, the Jacobians.
template <class T>
struct Data {
  Sensors<T> sensors_rad{};  ///< input of computeFromSensors, output of computeFromFinger
  // Θ_r and X (eq 4)
  T theta1_rad{};   ///< θ1 = θ1r
  T theta6r_rad{};  ///< θ6r
  T x3_m{};         ///< MCP slider
  T theta4_rad{};   ///< finger MCP
  T theta5_rad{};   ///< CE relative to the proximal phalanx (passive joint C)
  T theta7r_rad{};  ///< redundant sensor at F: θ5 + θ6r − θ8 − π/2 (wrapped)
  T theta8_rad{};   ///< finger PIP
  // DIP chain
  T theta_K_rad{};  ///< DIP chain sensor
  T x_dip_m{};      ///< distal slider
  T theta_dip_rad{};
  T abduction_rad{};
  /// Loop-closure residual of each chain (m): 0 when the exact solution exists, else the distance the
  /// least-squares pose misses by (eq 3–4 fallback).
  std::array<T, 3> residual_m{};
  std::array<bool, 3> least_squares{};  ///< per chain MCP, PIP, DIP: the fallback was used
  Mat42<T> J{};    ///< ∂X/∂Θ_r (eq 5)
  Mat2<T> J_n{};   ///< [[J21 J22] [J41 J42]] (eq 10): finger angle rates from exo rates
  T J_dip{};       ///< dθ_dip/dθ_K of the DIP chain
  bool J_valid = false;
  Status status = Status::kNonFiniteInput;
};

// ---------------------------------------------------------------------------------------------------------
// One slider chain (MCP: eq 3; DIP: same structure). Pivot at the origin, human joint at a = (a_x, a_y),
// input link of length l1 at angle θ_in, rest link of length l2 ⟂ phalanx, slider x along the phalanx whose
// direction is q: l1 e^{iθ_in} + l2 e^{i(q−π/2)} + x e^{i(q−π)} = a.
// ---------------------------------------------------------------------------------------------------------
namespace detail {

/// Wraps to (-π, π].
template <class T>
inline T wrapToPi(T a) {
  return std::remainder(a, T(2) * kPi<T>);
}

/// Sensor side → phalanx side. Exact: x = √(|c−a|² − l2²), q = ∠(c−a) − atan2(l2, x) with c = l1 e^{iθ_in}.
/// Least squares when |c−a| < l2 (no exact solution): x = 0, q = ∠(c−a) − π/2, residual = l2 − |c−a|.
/// Returns true when exact.
template <class T>
inline bool sliderFromInput(T a_x, T a_y, T l1, T l2, T theta_in, T& x, T& q, T& residual) {
  const T px = l1 * std::cos(theta_in) - a_x;
  const T py = l1 * std::sin(theta_in) - a_y;
  const T r2 = px * px + py * py;
  const T ang = std::atan2(py, px);
  if (r2 >= l2 * l2) {
    x = std::sqrt(r2 - l2 * l2);
    q = ang - std::atan2(l2, x);
    residual = T(0);
    return true;
  }
  x = T(0);
  q = ang - kPi<T> / T(2);
  residual = l2 - std::sqrt(r2);
  return false;
}

/// Phalanx side → sensor side. With u = e^{iq}, v = i·u: x = −a·u + √(l1² − (a·v + l2)²) (the distal root),
/// θ_in = ∠(a + x u + l2 v). Least squares when l1 < |a·v + l2|: x = −a·u, residual = |a·v + l2| − l1.
template <class T>
inline bool sliderFromOutput(T a_x, T a_y, T l1, T l2, T q, T& x, T& theta_in, T& residual) {
  const T ux = std::cos(q);
  const T uy = std::sin(q);
  const T au = a_x * ux + a_y * uy;
  const T av_l2 = -a_x * uy + a_y * ux + l2;
  const T disc = l1 * l1 - av_l2 * av_l2;
  bool exact = true;
  if (disc >= T(0)) {
    x = -au + std::sqrt(disc);
    residual = T(0);
  } else {
    x = -au;
    residual = std::fabs(av_l2) - l1;
    exact = false;
  }
  const T cx = a_x + x * ux - l2 * uy;
  const T cy = a_y + x * uy + l2 * ux;
  theta_in = std::atan2(cy, cx);
  return exact;
}

/// Velocity of the slider chain (implicit differentiation of eq 3, = appendix J11, J21 for the MCP chain):
/// dx/dθ_in = −l1 sin(θ_in − q) + l2 l1 cos(θ_in − q)/x,  dq/dθ_in = l1 cos(θ_in − q)/x.
template <class T>
inline void sliderRates(T l1, T l2, T theta_in, T q, T x, T& dx, T& dq) {
  const T phi = theta_in - q;
  dq = l1 * std::cos(phi) / x;
  dx = -l1 * std::sin(phi) + l2 * dq;
}

/// PIP loop in the proximal frame at H. c = C − H = (x3 − l_AH, l_CD).
template <class T>
struct PipGeometry {
  T c_x, c_y, l_CE, l_EF, l_FH, hfg;
};

template <class T>
inline PipGeometry<T> pipGeometry(const Model<T>& m, T x3) {
  return {x3 - m.subject.l_AH_m, m.subject.l_CD_m, m.fixed.l_CE_m, m.fixed.l_EF_m, lengthFH(m.subject),
          angleHFG(m.subject)};
}

/// Sensor side → finger side of the PIP chain: θ6r fixes |CF| = d (law of cosines); F is on the circle of radius
/// l_FH about H and on the circle of radius d about C, on the clockwise side of H→C (docs: branch). Least
/// squares when the circles do not meet: F on the line HC (nearest/farthest point), residual = ||CF| − d|.
/// `other_branch`: F on the counter-clockwise side of H→C instead (the other assembly mode of the four-bar; only
/// eq 12's fit uses it, for recordings that pass through the dead point).
template <class T>
inline bool pipFromInput(const PipGeometry<T>& g, T theta6r, T& theta5, T& theta8, T& residual,
                         bool other_branch = false) {
  const T d2 = g.l_CE * g.l_CE + g.l_EF * g.l_EF - T(2) * g.l_CE * g.l_EF * std::cos(theta6r);
  const T d = std::sqrt(d2 > T(0) ? d2 : T(0));
  const T rho = std::hypot(g.c_x, g.c_y);
  const T ux = g.c_x / rho;
  const T uy = g.c_y / rho;
  // F = a·ĉ − h·ĉ⊥ (ĉ⊥ = ĉ rotated +90°): clockwise of H→C.
  const T a = (g.l_FH * g.l_FH - d2 + rho * rho) / (T(2) * rho);
  const T h2 = g.l_FH * g.l_FH - a * a;
  T fx = T(0);
  T fy = T(0);
  bool exact = true;
  if (h2 >= T(0)) {
    const T h = other_branch ? -std::sqrt(h2) : std::sqrt(h2);
    fx = a * ux + h * uy;
    fy = a * uy - h * ux;
    residual = T(0);
  } else {
    const T s = a > T(0) ? T(1) : T(-1);  // d too short: nearest point; too long: farthest point
    fx = s * g.l_FH * ux;
    fy = s * g.l_FH * uy;
    residual = std::fabs(std::hypot(fx - g.c_x, fy - g.c_y) - d);
    exact = false;
  }
  theta8 = std::atan2(fy, fx) - kPi<T> / T(2) + g.hfg;
  // E left of C→F at the interior angle γ of triangle C-E-F (sides l_CE, l_EF, d).
  T cg = (g.l_CE * g.l_CE + d2 - g.l_EF * g.l_EF) / (T(2) * g.l_CE * (d > T(0) ? d : T(1)));
  cg = cg > T(1) ? T(1) : (cg < T(-1) ? T(-1) : cg);
  theta5 = std::atan2(fy - g.c_y, fx - g.c_x) + std::acos(cg);
  return exact;
}

/// Finger side → sensor side of the PIP chain: F from θ8, then the dyad C-E-F (E dorsal, θ6r ∈ (0, π)).
/// Least squares when |CF| is outside [|l_CE − l_EF|, l_CE + l_EF]: the dyad is stretched/folded flat.
template <class T>
inline bool pipFromOutput(const PipGeometry<T>& g, T theta8, T& theta5, T& theta6r, T& residual) {
  const T psi = theta8 + kPi<T> / T(2) - g.hfg;
  const T fx = g.l_FH * std::cos(psi);
  const T fy = g.l_FH * std::sin(psi);
  const T dx = fx - g.c_x;
  const T dy = fy - g.c_y;
  const T d = std::hypot(dx, dy);
  const T c5 = (g.l_CE * g.l_CE + d * d - g.l_EF * g.l_EF) / (T(2) * g.l_CE * d);
  const T c6 = (g.l_CE * g.l_CE + g.l_EF * g.l_EF - d * d) / (T(2) * g.l_CE * g.l_EF);
  bool exact = c5 >= T(-1) && c5 <= T(1) && c6 >= T(-1) && c6 <= T(1);
  const T c5c = c5 > T(1) ? T(1) : (c5 < T(-1) ? T(-1) : c5);
  const T c6c = c6 > T(1) ? T(1) : (c6 < T(-1) ? T(-1) : c6);
  theta5 = std::atan2(dy, dx) + std::acos(c5c);
  theta6r = std::acos(c6c);
  if (exact) {
    residual = T(0);
  } else {
    const T reach_max = g.l_CE + g.l_EF;
    const T reach_min = std::fabs(g.l_CE - g.l_EF);
    residual = d > reach_max ? d - reach_max : reach_min - d;
  }
  return exact;
}

/// Partial derivatives of (θ5, θ8) w.r.t. x3 and θ6r from the PIP loop G(θ5, θ8; x3, θ6r) = 0:
///   ∂G/∂θ5 = i·w (w = C→F through the dyad), ∂G/∂θ8 = −i·f (f = H→F), ∂G/∂x3 = 1,
///   ∂G/∂θ6r = −i·e (e = l_EF e^{i(θ5+θ6r)}).
/// Returns false when the 2×2 is singular (F, H, C collinear: the four-bar's dead point).
template <class T>
inline bool pipRates(const PipGeometry<T>& g, T theta5, T theta6r, T theta8, T min_det, T& d5_dx3, T& d8_dx3,
                     T& d5_d6, T& d8_d6) {
  const T ex = g.l_EF * std::cos(theta5 + theta6r);
  const T ey = g.l_EF * std::sin(theta5 + theta6r);
  const T wx = g.l_CE * std::cos(theta5) - ex;
  const T wy = g.l_CE * std::sin(theta5) - ey;
  const T psi = theta8 + kPi<T> / T(2) - g.hfg;
  const T fx = g.l_FH * std::cos(psi);
  const T fy = g.l_FH * std::sin(psi);
  // Columns of M (real, imag): i·w = (−w_y, w_x), −i·f = (f_y, −f_x).
  const T m00 = -wy;
  const T m10 = wx;
  const T m01 = fy;
  const T m11 = -fx;
  const T det = m00 * m11 - m01 * m10;
  if (!(std::fabs(det) > min_det)) return false;
  // M·[d5 d8]ᵀ = −∂G/∂p for p = x3: −(1, 0); p = θ6r: i·e = (−e_y, e_x).
  const T b0x = T(-1);
  const T b1x = T(0);
  d5_dx3 = (b0x * m11 - m01 * b1x) / det;
  d8_dx3 = (m00 * b1x - b0x * m10) / det;
  const T b06 = -ey;
  const T b16 = ex;
  d5_d6 = (b06 * m11 - m01 * b16) / det;
  d8_d6 = (m00 * b16 - b06 * m10) / det;
  return true;
}

/// Redundant sensor at F: θ7r = ∠(F→E) − ∠(G→F) = θ5 + θ6r − θ8 − π/2, wrapped to (−π, π].
template <class T>
inline T redundantAngle(T theta5, T theta6r, T theta8) {
  return wrapToPi(theta5 + theta6r - theta8 - kPi<T> / T(2));
}

template <class T>
inline bool allFinite(const Sensors<T>& s) {
  for (const T v : s) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

template <class T>
inline void clearOutputs(Data<T>& d) {
  const Sensors<T> keep = d.sensors_rad;
  d = Data<T>{};
  d.sensors_rad = keep;
}

}  // namespace detail

// ---------------------------------------------------------------------------------------------------------
// Jacobians (eq 5, 10) and statics (eq 6, 9)
// ---------------------------------------------------------------------------------------------------------

/// J = ∂X/∂Θ_r (eq 5) and J_n (eq 10) for the pose already in `d` (from computeFromSensors/-Finger).
/// Implicit differentiation of the MCP loop (eq 3) and the PIP loop; equal to the appendix's eq 19 where that
/// can be checked (J11, J21, J32, J42; tests). kSingular (J = 0, J_valid = false) when x3 < min_slider_m or
/// the PIP loop is at a dead point.
template <class T>
inline Status computeJacobian(const Model<T>& m, Data<T>& d) {
  d.J = Mat42<T>{};
  d.J_n = Mat2<T>{};
  d.J_dip = T(0);
  d.J_valid = false;
  if (!(d.x3_m >= m.min_slider_m)) return Status::kSingular;
  T dx3 = T(0);
  T dq4 = T(0);
  detail::sliderRates(m.subject.l_BC_m, m.subject.l_CD_m, d.theta1_rad, d.theta4_rad, d.x3_m, dx3, dq4);
  const detail::PipGeometry<T> g = detail::pipGeometry(m, d.x3_m);
  T d5_dx3 = T(0);
  T d8_dx3 = T(0);
  T d5_d6 = T(0);
  T d8_d6 = T(0);
  if (!detail::pipRates(g, d.theta5_rad, d.theta6r_rad, d.theta8_rad, m.min_pip_det_m2, d5_dx3, d8_dx3, d5_d6,
                        d8_d6)) {
    return Status::kSingular;
  }
  d.J[0] = {dx3, T(0)};
  d.J[1] = {dq4, T(0)};
  d.J[2] = {d5_dx3 * dx3, d5_d6};
  d.J[3] = {d8_dx3 * dx3, d8_d6};
  d.J_n = {{{d.J[1][0], d.J[1][1]}, {d.J[3][0], d.J[3][1]}}};
  if (d.x_dip_m >= m.min_slider_m) {
    T dxd = T(0);
    detail::sliderRates(m.fixed.l_KL_m, m.fixed.l_LM_m, d.theta_K_rad, d.theta_dip_rad, d.x_dip_m, dxd, d.J_dip);
  }
  d.J_valid = true;
  return Status::kOk;
}

/// Exoskeleton joint torques from finger joint torques (eq 6 with f3 = τ5 = 0): τ_j = J_nᵀ τ_f.
/// τ_f = (τ_mcp, τ_pip) N·m applied TO the finger joints (positive = in the direction of increasing θ4, θ8,
/// i.e. extension); τ_j = (τ_j,mcp, τ_j,pip) N·m at θ1r, θ6r.
template <class T>
inline Vec2<T> exoTorqueFromFingerTorque(const Mat2<T>& J_n, const Vec2<T>& tau_f_Nm) {
  return {J_n[0][0] * tau_f_Nm[0] + J_n[1][0] * tau_f_Nm[1], J_n[0][1] * tau_f_Nm[0] + J_n[1][1] * tau_f_Nm[1]};
}

/// Finger joint torques from exoskeleton joint torques (eq 9): τ_f = J_n^{-T} τ_j. kSingular (and 0) when
/// |det J_n| ≤ min_abs_det.
template <class T>
inline Status fingerTorqueFromExoTorque(const Mat2<T>& J_n, const Vec2<T>& tau_j_Nm, T min_abs_det,
                                        Vec2<T>& tau_f_Nm) {
  const T det = J_n[0][0] * J_n[1][1] - J_n[0][1] * J_n[1][0];
  if (!(std::fabs(det) > min_abs_det)) {
    tau_f_Nm = {T(0), T(0)};
    return Status::kSingular;
  }
  // J_nᵀ = [[a c] [b d]] with J_n = [[a b] [c d]]; (J_nᵀ)^{-1} = 1/det [[d −c] [−b a]].
  tau_f_Nm = {(J_n[1][1] * tau_j_Nm[0] - J_n[1][0] * tau_j_Nm[1]) / det,
              (-J_n[0][1] * tau_j_Nm[0] + J_n[0][0] * tau_j_Nm[1]) / det};
  return Status::kOk;
}

/// Time derivative of J_n by the backward difference of eq 20: (J_n(t) − J_n(t − Δt)) / Δt.
template <class T>
inline Mat2<T> jacobianNRate(const Mat2<T>& J_n_now, const Mat2<T>& J_n_prev, T dt_s) {
  Mat2<T> r{};
  for (std::size_t i = 0; i < 2; ++i) {
    for (std::size_t j = 0; j < 2; ++j) r[i][j] = (J_n_now[i][j] - J_n_prev[i][j]) / dt_s;
  }
  return r;
}

// ---------------------------------------------------------------------------------------------------------
// Position kinematics in both directions
// ---------------------------------------------------------------------------------------------------------

/// Host estimator (eq 3–4, §7.4): the five sensor readings → the full pose, chain by chain MCP → PIP → DIP,
/// each by its closed-form four-bar solution, with the least-squares pose when a chain cannot close; then J, J_n.
/// Returns kOk, kLeastSquares (pose usable; `least_squares`/`residual_m` say which chain), kSingular (pose
/// usable, J not), or kNonFiniteInput (all outputs 0).
template <class T>
inline Status computeFromSensors(const Model<T>& m, const Sensors<T>& sensors_rad, Data<T>& d) {
  d.sensors_rad = sensors_rad;
  detail::clearOutputs(d);
  if (!detail::allFinite(sensors_rad)) {
    d.status = Status::kNonFiniteInput;
    return d.status;
  }
  const SubjectParams<T>& p = m.subject;
  d.theta1_rad = sensors_rad[kSensorExoMcp];
  d.theta6r_rad = sensors_rad[kSensorExoPip];
  d.theta_K_rad = sensors_rad[kSensorDip];
  d.abduction_rad = sensors_rad[kSensorAbduction];
  // MCP chain (eq 3).
  d.least_squares[0] = !detail::sliderFromInput(p.x_A_m, p.y_A_m, p.l_BC_m, p.l_CD_m, d.theta1_rad, d.x3_m,
                                                d.theta4_rad, d.residual_m[0]);
  d.theta4_rad = detail::wrapToPi(d.theta4_rad);
  // PIP chain, with the MCP chain's solution fixed.
  const detail::PipGeometry<T> g = detail::pipGeometry(m, d.x3_m);
  d.least_squares[1] = !detail::pipFromInput(g, d.theta6r_rad, d.theta5_rad, d.theta8_rad, d.residual_m[1]);
  d.theta5_rad = detail::wrapToPi(d.theta5_rad);
  d.theta8_rad = detail::wrapToPi(d.theta8_rad);
  d.theta7r_rad = detail::redundantAngle(d.theta5_rad, d.theta6r_rad, d.theta8_rad);
  // DIP chain, with the PIP chain's solution fixed (its frame is the middle phalanx).
  d.least_squares[2] =
      !detail::sliderFromInput(m.fixed.l_HI_m - m.fixed.x_K_m, -m.fixed.y_K_m, m.fixed.l_KL_m, m.fixed.l_LM_m,
                               d.theta_K_rad, d.x_dip_m, d.theta_dip_rad, d.residual_m[2]);
  d.theta_dip_rad = detail::wrapToPi(d.theta_dip_rad);
  const Status js = computeJacobian(m, d);
  const bool ls = d.least_squares[0] || d.least_squares[1] || d.least_squares[2];
  d.status = js != Status::kOk ? js : (ls ? Status::kLeastSquares : Status::kOk);
  return d.status;
}

/// Simulated plant / synthetic data: finger joint angles → exoskeleton pose and all five sensor readings
/// (including the redundant θ5), then J, J_n. kLeastSquares when the finger pose is outside what the
/// mechanism can assemble (closest pose returned), kSingular when J does not exist there.
template <class T>
inline Status computeFromFinger(const Model<T>& m, const FingerAngles<T>& finger, Data<T>& d) {
  d = Data<T>{};
  if (!std::isfinite(finger.mcp_rad) || !std::isfinite(finger.pip_rad) || !std::isfinite(finger.dip_rad) ||
      !std::isfinite(finger.abduction_rad)) {
    d.status = Status::kNonFiniteInput;
    return d.status;
  }
  const SubjectParams<T>& p = m.subject;
  d.theta4_rad = finger.mcp_rad;
  d.theta8_rad = finger.pip_rad;
  d.theta_dip_rad = finger.dip_rad;
  d.abduction_rad = finger.abduction_rad;
  d.least_squares[0] = !detail::sliderFromOutput(p.x_A_m, p.y_A_m, p.l_BC_m, p.l_CD_m, d.theta4_rad, d.x3_m,
                                                 d.theta1_rad, d.residual_m[0]);
  const detail::PipGeometry<T> g = detail::pipGeometry(m, d.x3_m);
  d.least_squares[1] = !detail::pipFromOutput(g, d.theta8_rad, d.theta5_rad, d.theta6r_rad, d.residual_m[1]);
  d.theta5_rad = detail::wrapToPi(d.theta5_rad);
  d.theta7r_rad = detail::redundantAngle(d.theta5_rad, d.theta6r_rad, d.theta8_rad);
  d.least_squares[2] =
      !detail::sliderFromOutput(m.fixed.l_HI_m - m.fixed.x_K_m, -m.fixed.y_K_m, m.fixed.l_KL_m, m.fixed.l_LM_m,
                                d.theta_dip_rad, d.x_dip_m, d.theta_K_rad, d.residual_m[2]);
  d.sensors_rad[kSensorExoMcp] = d.theta1_rad;
  d.sensors_rad[kSensorExoPip] = d.theta6r_rad;
  d.sensors_rad[kSensorRedundant] = d.theta7r_rad;
  d.sensors_rad[kSensorDip] = d.theta_K_rad;
  d.sensors_rad[kSensorAbduction] = d.abduction_rad;
  const Status js = computeJacobian(m, d);
  const bool ls = d.least_squares[0] || d.least_squares[1] || d.least_squares[2];
  d.status = js != Status::kOk ? js : (ls ? Status::kLeastSquares : Status::kOk);
  return d.status;
}

/// Model-based redundant sensor reading y_m (eq 12): θ7r predicted from θ1r and θ6r with parameters `p`.
/// `residual_m` (optional) receives the larger chain residual. Used by the parameter estimator.
template <class T>
inline T predictRedundant(const SubjectParams<T>& p, const FixedGeometry<T>& fixed, T theta1r_rad, T theta6r_rad,
                          T* residual_m = nullptr, bool other_branch = false) {
  Model<T> m{};
  m.subject = p;
  m.fixed = fixed;
  T x3 = T(0);
  T q4 = T(0);
  T r0 = T(0);
  detail::sliderFromInput(p.x_A_m, p.y_A_m, p.l_BC_m, p.l_CD_m, theta1r_rad, x3, q4, r0);
  T t5 = T(0);
  T t8 = T(0);
  T r1 = T(0);
  detail::pipFromInput(detail::pipGeometry(m, x3), theta6r_rad, t5, t8, r1, other_branch);
  if (residual_m != nullptr) *residual_m = r0 > r1 ? r0 : r1;
  return detail::redundantAngle(t5, theta6r_rad, t8);
}

}  // namespace phalanx::sea
