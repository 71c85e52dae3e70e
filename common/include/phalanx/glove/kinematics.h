#pragma once
/// RML five-finger glove: kinematics of one finger/glove six-bar (Ma & Ben-Tzvi 2015, seeds/000 §3.1).
///
/// Header-only, freestanding C++17 (no heap, no exceptions, no iostream), templated on the scalar type:
/// `double` on the host, `float` on the microcontroller. Pinocchio style: a const `Model<T>` (geometry) and a
/// preallocated `Data<T>` workspace that `computeFromAlpha()` / `computeFromTheta()` write into.
///
/// Frames and conventions (docs/glove-model.md has the figure-level description):
///  - {O}: finger base frame, planar. Origin at the MCP joint axis A0, x_O along the fully extended finger
///    (distal), y_O dorsal (out of the back of the hand). Angles are counter-clockwise about z_O = x_O × y_O,
///    so flexion is NEGATIVE, as in Table 2 (MCP [-90, 30]°, PIP [-120, 0]°, DIP [-80, 0]°).
///  - θ = (θ1, θ2, θ3): finger joint angles MCP, PIP, DIP (relative angles, rad).
///  - α = (α1, α2, α3): glove mechanism joint angles at B0, B1, B2 (relative angles, rad); these are what the
///    15 Hall sensors measure.
///  - u = (x_A3, y_A3, φ): fingertip pose in {O} (m, m, rad), φ = Σθ = Σα wrapped to (-π, π].
///  - Jacobians J[row][col], row = (x, y, φ), col = joint 1..3.
///  - Planar wrench at the fingertip point A3 in {O}: F = (f_x N, f_y N, m_z N·m).
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

namespace phalanx::glove {

template <class T>
using Vec3 = std::array<T, 3>;
/// Row-major 3×3 matrix, M[row][col].
template <class T>
using Mat3 = std::array<std::array<T, 3>, 3>;

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

/// Result of a kinematic computation. Faults 1..15, "limit active" (result usable, but clamped) from 16.
enum class Status : std::uint8_t {
  kOk = 0,
  kUnreachable = 1,     ///< no (elbow-up / anatomical) solution: outputs are left at 0, never NaN
  kNonFiniteInput = 2,  ///< NaN or Inf in the input: outputs are left at 0
  kSingular = 3,        ///< a matrix to be inverted is numerically singular: output left at 0
  kReachClamped = 16,   ///< fingertip was beyond the finger's reach by ≤ Model::reach_tolerance_m; θ clamped
};

/// True when the outputs of a call that returned `s` may be used.
constexpr bool isUsable(Status s) { return s == Status::kOk || s == Status::kReachClamped; }

/// Finger order everywhere in the glove code (telemetry samples 3·finger + joint).
enum class FingerId : std::uint8_t { kThumb = 0, kIndex = 1, kMiddle = 2, kRing = 3, kLittle = 4 };
inline constexpr std::size_t kNumFingers = 5;

/// Human finger: link lengths p_i = |A_{i-1} A_i| (m) and joint ranges (rad), Table 2.
template <class T>
struct FingerGeometry {
  T p1_m{};  ///< proximal phalanx, MCP → PIP
  T p2_m{};  ///< middle phalanx, PIP → DIP
  T p3_m{};  ///< distal phalanx, DIP → fingertip point A3
  Vec3<T> theta_min_rad{};
  Vec3<T> theta_max_rad{};
};

/// Glove finger mechanism (eq 3–4 left-hand side), all in the finger base frame {O}.
template <class T>
struct MechanismGeometry {
  T l1_m{};  ///< |B0 B1| (the L-shaped link 1, pivot to pivot), Table 3
  T l2_m{};  ///< |B1 B2|, Table 3
  T l3_m{};  ///< |B2 B3|, Table 3 (= p3: link 3 rides parallel to the distal phalanx)
  /// SIGNED offset of the fingertip A3 from B3 along the +90° normal of link 3, exactly as in eq 3–4:
  /// A3 = B3 + l_p·(cos(90°+φ), sin(90°+φ)). The mechanism is on the dorsal side, i.e. B3 is dorsal of A3,
  /// so with the y-dorsal frame above l_p is NEGATIVE (see docs/glove-model.md §"l_p sign").
  T l_p_m{};
  T x_B0_m{};  ///< base pivot B0 in {O}: negative = proximal of the MCP axis
  T y_B0_m{};  ///< base pivot B0 in {O}: positive = dorsal of the MCP axis
  /// Range of α over Table 2's finger range for this geometry (used for the g3 check and the capstan
  /// wrap model of capstan.h). Computed by the tests, rounded outwards to whole degrees.
  Vec3<T> alpha_min_rad{};
  Vec3<T> alpha_max_rad{};
};

/// Geometry of one finger + its glove mechanism, plus numerical tolerances.
template <class T>
struct Model {
  FingerGeometry<T> finger{};
  MechanismGeometry<T> mech{};
  /// |sin α2| (eq 24) and |sin θ2| below this raise the near-singular flags in Data. 0.2 ≈ 11.5° from the
  /// singular pose; the working range of α2 for the default geometry keeps |sin α2| ≥ 0.57.
  T near_singular_sin = T(0.2);
  /// A fingertip pose up to this far beyond the finger's reach (measurement noise, finger length measured
  /// with a ruler) is clamped to the straight/fully-folded finger and reported as kReachClamped. 2 mm ≈ the
  /// uncertainty of a ruler-measured finger length (paper §4.3).
  T reach_tolerance_m = T(0.002);
};

/// Workspace written by computeFromAlpha() / computeFromTheta(); preallocate once, reuse every cycle.
template <class T>
struct Data {
  Vec3<T> alpha_rad{};      ///< mechanism angles (input of computeFromAlpha, output of computeFromTheta)
  Vec3<T> theta_rad{};      ///< finger angles
  Vec3<T> O_u_tip{};        ///< fingertip pose (x_m, y_m, phi_rad) in {O}
  Mat3<T> J_theta_u{};      ///< ∂u/∂θ, eq 9 (finger Jacobian)
  Mat3<T> J_alpha_u{};      ///< ∂u/∂α, eq 9 (mechanism Jacobian, a22 corrected)
  Mat3<T> J_alpha_theta{};  ///< ∂θ/∂α = (J_θ^u)^{-1} J_α^u, eq 11; zero unless J_alpha_theta_valid
  T det_J_alpha_u{};        ///< eq 24: l1·l2·sin α2 (m²)
  T det_J_theta_u{};        ///< p1·p2·sin θ2 (m²)
  bool alpha_near_singular = false;  ///< |sin α2| < near_singular_sin (eq 24 margin)
  bool theta_near_singular = false;  ///< |sin θ2| < near_singular_sin (finger straight at PIP)
  bool J_alpha_theta_valid = false;  ///< J_θ^u was invertible
  bool theta_within_range = false;   ///< θ inside FingerGeometry's [theta_min, theta_max]
  Status status = Status::kNonFiniteInput;
};

// ---------------------------------------------------------------------------------------------------------
// Small helpers
// ---------------------------------------------------------------------------------------------------------

/// Wraps an angle to [-π, π] (rad).
template <class T>
inline T wrapToPi(T a) {
  // Same result as std::remainder(a, 2π), without its cost on the simulation's inner loop: |a| ≤ π is
  // returned as it is (remainder's quotient rounds to 0, the tie included), and π < |a| < 3π, except
  // |a| = 2π (remainder gives a zero with a's sign), loses one period exactly (a and 2π are within a factor
  // of 2, so the subtraction is exact: Sterbenz).
  const T two_pi = T(2) * kPi<T>;
  const T mag = std::fabs(a);
  if (mag <= kPi<T>) return a;
  if (mag < T(3) * kPi<T> && mag != two_pi) return a > T(0) ? a - two_pi : a + two_pi;
  return std::remainder(a, two_pi);
}

template <class T>
inline bool allFinite(const Vec3<T>& v) {
  return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

template <class T>
inline T clampTo(T v, T lo, T hi) {
  return v < lo ? lo : (v > hi ? hi : v);
}

/// y = M·x
template <class T>
inline Vec3<T> mul(const Mat3<T>& m, const Vec3<T>& x) {
  return {m[0][0] * x[0] + m[0][1] * x[1] + m[0][2] * x[2], m[1][0] * x[0] + m[1][1] * x[1] + m[1][2] * x[2],
          m[2][0] * x[0] + m[2][1] * x[1] + m[2][2] * x[2]};
}

/// y = Mᵀ·x
template <class T>
inline Vec3<T> mulTransposed(const Mat3<T>& m, const Vec3<T>& x) {
  return {m[0][0] * x[0] + m[1][0] * x[1] + m[2][0] * x[2], m[0][1] * x[0] + m[1][1] * x[1] + m[2][1] * x[2],
          m[0][2] * x[0] + m[1][2] * x[1] + m[2][2] * x[2]};
}

// ---------------------------------------------------------------------------------------------------------
// Default geometry
// ---------------------------------------------------------------------------------------------------------

namespace detail {
/// All lengths in mm, angles in degrees (converted once).
template <class T>
inline Model<T> makeModel(T p1, T p2, T p3, T l1, T l2, T l_p, T x_b0, T y_b0, const Vec3<T>& a_min_deg,
                          const Vec3<T>& a_max_deg) {
  const T mm = T(1e-3);
  Model<T> m{};
  m.finger.p1_m = p1 * mm;
  m.finger.p2_m = p2 * mm;
  m.finger.p3_m = p3 * mm;
  // Table 2 ranges, used for every finger (the paper treats all five fingers alike, §3.3).
  m.finger.theta_min_rad = {degToRad(T(-90)), degToRad(T(-120)), degToRad(T(-80))};
  m.finger.theta_max_rad = {degToRad(T(30)), degToRad(T(0)), degToRad(T(0))};
  m.mech.l1_m = l1 * mm;
  m.mech.l2_m = l2 * mm;
  m.mech.l3_m = p3 * mm;  // l3 = p3: the paper's optimum (Table 3: l3 converged to p3 = 19.1 mm)
  m.mech.l_p_m = l_p * mm;
  m.mech.x_B0_m = x_b0 * mm;
  m.mech.y_B0_m = y_b0 * mm;
  for (std::size_t i = 0; i < 3; ++i) {
    m.mech.alpha_min_rad[i] = degToRad(a_min_deg[i]);
    m.mech.alpha_max_rad[i] = degToRad(a_max_deg[i]);
  }
  return m;
}
}  // namespace detail

/// Default geometry of one finger (docs/glove-model.md §"Constants" gives the source of every number).
///
/// Finger lengths: index = Table 2. The other fingers scale the index finger with the segment/hand-length
/// ratios of Buchholz, Armstrong & Goldstein (Ergonomics 35(3), 1992) for the same hand length
/// HL = 197 mm (Table 2 itself is 197 mm × 0.245 / 0.143 / 0.097). The thumb is a planar 3-link finger
/// (metacarpal, proximal, distal: 0.251 / 0.196 / 0.158 HL) driven through Table 2's ranges, as in the paper.
/// Mechanism: l1, l2 of Table 3 scaled by Σp / Σp_index, l3 = p3; l_p, x_B0, y_B0 chosen per finger (not
/// given in the paper) so that the full Table 2 range is reachable elbow-up, α stays close to Table 3 and
/// every α_i,var < 150° (constraint g3, eq 22) with ≥ 4° margin.
template <class T>
inline Model<T> defaultModel(FingerId finger) {
  //                                p1      p2     p3     l1     l2     l_p     x_B0    y_B0   (mm)
  switch (finger) {
    case FingerId::kThumb:
      return detail::makeModel<T>(T(49.4), T(38.6), T(31.1), T(92.08), T(58.87), T(-14.0), T(-16.0), T(21.0),
                                  {T(-86), T(-145), T(-68)}, {T(60), T(-65), T(79)});
    case FingerId::kMiddle:
      return detail::makeModel<T>(T(52.4), T(33.5), T(21.3), T(82.84), T(52.96), T(-14.0), T(-10.5), T(17.5),
                                  {T(-84), T(-137), T(-74)}, {T(63), T(-57), T(73)});
    case FingerId::kRing:
      return detail::makeModel<T>(T(48.1), T(32.5), T(21.1), T(78.58), T(50.24), T(-13.5), T(-11.0), T(17.5),
                                  {T(-85), T(-138), T(-73)}, {T(62), T(-55), T(74)});
    case FingerId::kLittle:
      return detail::makeModel<T>(T(40.2), T(23.0), T(18.3), T(63.02), T(40.29), T(-12.0), T(-9.5), T(12.0),
                                  {T(-82), T(-139), T(-76)}, {T(64), T(-59), T(72)});
    case FingerId::kIndex:
    default:
      return detail::makeModel<T>(T(48.3), T(28.2), T(19.1), T(73.88), T(47.23), T(-12.5), T(-10.0), T(14.0),
                                  {T(-82), T(-137), T(-76)}, {T(63), T(-59), T(71)});
  }
}

/// Index finger: Table 2 finger, Table 3 mechanism (l1 = 73.88, l2 = 47.23, l3 = 19.1 mm).
template <class T>
inline Model<T> defaultIndexModel() {
  return defaultModel<T>(FingerId::kIndex);
}

// ---------------------------------------------------------------------------------------------------------
// Forward kinematics, eq 3–5
// ---------------------------------------------------------------------------------------------------------

/// Fingertip pose u = (x_m, y_m, φ_rad) in {O} from the finger angles θ (eq 3–5, right-hand side).
/// Sines and cosines of the finger's cumulative angles θ1, θ1+θ2, θ1+θ2+θ3: what tipPoseFromTheta,
/// jacobianThetaU and alphaFromTheta share, so that a caller needing all three computes them once.
template <class T>
struct ThetaTrig {
  T t123 = T(0);  ///< θ1+θ2+θ3 (rad), not wrapped
  T s1 = T(0), c1 = T(0), s12 = T(0), c12 = T(0), s123 = T(0), c123 = T(0);
};

template <class T>
inline ThetaTrig<T> thetaTrig(const Vec3<T>& theta_rad) {
  const T t1 = theta_rad[0];
  const T t12 = t1 + theta_rad[1];
  ThetaTrig<T> tr;
  tr.t123 = t12 + theta_rad[2];
  tr.s1 = std::sin(t1);
  tr.c1 = std::cos(t1);
  tr.s12 = std::sin(t12);
  tr.c12 = std::cos(t12);
  tr.s123 = std::sin(tr.t123);
  tr.c123 = std::cos(tr.t123);
  return tr;
}

/// tipPoseFromTheta from precomputed thetaTrig(θ).
template <class T>
inline Vec3<T> tipPoseFromTheta(const FingerGeometry<T>& f, const ThetaTrig<T>& tr) {
  return {f.p1_m * tr.c1 + f.p2_m * tr.c12 + f.p3_m * tr.c123, f.p1_m * tr.s1 + f.p2_m * tr.s12 + f.p3_m * tr.s123,
          wrapToPi(tr.t123)};
}

template <class T>
inline Vec3<T> tipPoseFromTheta(const FingerGeometry<T>& f, const Vec3<T>& theta_rad) {
  return tipPoseFromTheta(f, thetaTrig(theta_rad));
}

/// Fingertip pose u = (x_m, y_m, φ_rad) in {O} from the mechanism angles α (eq 3–5, left-hand side):
/// x = x_B0 + l1 c1 + l2 c12 + l3 c123 + l_p cos(90°+α123) = … − l_p s123,
/// y = y_B0 + l1 s1 + l2 s12 + l3 s123 + l_p sin(90°+α123) = … + l_p c123.
template <class T>
inline Vec3<T> tipPoseFromAlpha(const MechanismGeometry<T>& m, const Vec3<T>& alpha_rad) {
  const T a1 = alpha_rad[0];
  const T a12 = a1 + alpha_rad[1];
  const T a123 = a12 + alpha_rad[2];
  const T c123 = std::cos(a123);
  const T s123 = std::sin(a123);
  return {m.x_B0_m + m.l1_m * std::cos(a1) + m.l2_m * std::cos(a12) + m.l3_m * c123 - m.l_p_m * s123,
          m.y_B0_m + m.l1_m * std::sin(a1) + m.l2_m * std::sin(a12) + m.l3_m * s123 + m.l_p_m * c123,
          wrapToPi(a123)};
}

// ---------------------------------------------------------------------------------------------------------
// Inverse kinematics
// ---------------------------------------------------------------------------------------------------------

namespace detail {
/// Tolerance on |cos| − 1 accepted as pure rounding (≈ 2e-13 for double, 1.2e-4 for float, i.e. ≈ 2 µm of
/// over-reach on the index finger in float).
template <class T>
constexpr T cosRoundingTolerance() {
  return T(1024) * std::numeric_limits<T>::epsilon();
}

/// Elbow angle of a planar 2R chain (link lengths a, b) reaching distance² r2, for the branch with a
/// NEGATIVE (clockwise) elbow angle. Returns false when the distance is outside [|a−b|, a+b] by more than
/// `reach_tol_m`; sets `clamped` when it was outside by less.
template <class T>
inline bool elbowDownwardAngle(T a, T b, T r2, T reach_tol_m, T& elbow_rad, bool& clamped) {
  T c = (r2 - a * a - b * b) / (T(2) * a * b);
  clamped = false;
  const T tol = cosRoundingTolerance<T>();
  if (c > T(1) + tol || c < T(-1) - tol) {
    const T r = std::sqrt(r2);
    const T over = c > T(1) ? r - (a + b) : std::fabs(a - b) - r;
    if (!(over <= reach_tol_m)) return false;
    clamped = true;
  }
  c = clampTo(c, T(-1), T(1));
  elbow_rad = -std::acos(c);
  return true;
}
}  // namespace detail

/// Mechanism angles α from finger angles θ, elbow-up branch (eq 6–8, corrected; docs/glove-model.md):
///   M = −x_B0 + p1 c_θ1 + p2 c_θ12 + (p3 − l3) c_θ123 + l_p s_θ123      (B2 − B0, x)
///   N = −y_B0 + p1 s_θ1 + p2 s_θ12 + (p3 − l3) s_θ123 − l_p c_θ123      (B2 − B0, y)
///   α2 = −arccos((M² + N² − l1² − l2²) / (2 l1 l2))                       (eq 7, elbow up ⇔ α2 < 0)
///   α1 = atan2(N, M) + arccos((l1² − l2² + M² + N²) / (2 l1 √(M² + N²)))  (eq 6), computed in the
///        equivalent form atan2(N, M) − atan2(l2 sin α2, l1 + l2 cos α2)
///   α3 = θ1 + θ2 + θ3 − α1 − α2                                           (eq 8), wrapped to [-π, π]
/// Returns kUnreachable when B2 is out of the mechanism's reach (α is then set to 0).
/// alphaFromTheta with precomputed thetaTrig(θ) (θ must be finite; the overload below checks).
template <class T>
inline Status alphaFromTheta(const Model<T>& model, const ThetaTrig<T>& tr, Vec3<T>& alpha_rad) {
  alpha_rad = {T(0), T(0), T(0)};
  const FingerGeometry<T>& f = model.finger;
  const MechanismGeometry<T>& m = model.mech;
  const T phi = tr.t123;
  const T c_phi = tr.c123;
  const T s_phi = tr.s123;
  const T M = -m.x_B0_m + f.p1_m * tr.c1 + f.p2_m * tr.c12 + (f.p3_m - m.l3_m) * c_phi + m.l_p_m * s_phi;
  const T N = -m.y_B0_m + f.p1_m * tr.s1 + f.p2_m * tr.s12 + (f.p3_m - m.l3_m) * s_phi - m.l_p_m * c_phi;
  T a2 = T(0);
  bool clamped = false;
  // The mechanism has no reach tolerance: the finger pose is exact, so only rounding is accepted.
  if (!detail::elbowDownwardAngle(m.l1_m, m.l2_m, M * M + N * N, T(0), a2, clamped)) {
    return Status::kUnreachable;
  }
  const T a1 = wrapToPi(std::atan2(N, M) - std::atan2(m.l2_m * std::sin(a2), m.l1_m + m.l2_m * std::cos(a2)));
  alpha_rad = {a1, a2, wrapToPi(phi - a1 - a2)};
  return Status::kOk;
}

template <class T>
inline Status alphaFromTheta(const Model<T>& model, const Vec3<T>& theta_rad, Vec3<T>& alpha_rad) {
  alpha_rad = {T(0), T(0), T(0)};
  if (!allFinite(theta_rad)) return Status::kNonFiniteInput;
  return alphaFromTheta(model, thetaTrig(theta_rad), alpha_rad);
}

/// Finger angles θ from mechanism angles α (what the host needs: the Hall sensors measure α).
/// u from eq 3–5 (left-hand side), then planar 3R inverse kinematics of the finger with φ known:
/// DIP joint A2 = A3 − p3 (cos φ, sin φ); θ2 = −arccos((|A2|² − p1² − p2²)/(2 p1 p2)) (the anatomical
/// branch: PIP flexes, θ2 ≤ 0); θ1 = atan2(A2) − atan2(p2 sin θ2, p1 + p2 cos θ2); θ3 = φ − θ1 − θ2.
/// Returns kReachClamped when the fingertip was beyond reach by ≤ reach_tolerance_m (θ2 clamped to 0 or
/// −π), kUnreachable beyond that (θ set to 0).
template <class T>
inline Status thetaFromAlpha(const Model<T>& model, const Vec3<T>& alpha_rad, Vec3<T>& theta_rad) {
  theta_rad = {T(0), T(0), T(0)};
  if (!allFinite(alpha_rad)) return Status::kNonFiniteInput;
  const FingerGeometry<T>& f = model.finger;
  const MechanismGeometry<T>& m = model.mech;
  const T a1 = alpha_rad[0];
  const T a12 = a1 + alpha_rad[1];
  const T phi = a12 + alpha_rad[2];
  const T c_phi = std::cos(phi);
  const T s_phi = std::sin(phi);
  // A2 = A3 − p3 (c φ, s φ), with A3 from eq 3–4 (left-hand side).
  const T x2 = m.x_B0_m + m.l1_m * std::cos(a1) + m.l2_m * std::cos(a12) + (m.l3_m - f.p3_m) * c_phi -
               m.l_p_m * s_phi;
  const T y2 = m.y_B0_m + m.l1_m * std::sin(a1) + m.l2_m * std::sin(a12) + (m.l3_m - f.p3_m) * s_phi +
               m.l_p_m * c_phi;
  T t2 = T(0);
  bool clamped = false;
  if (!detail::elbowDownwardAngle(f.p1_m, f.p2_m, x2 * x2 + y2 * y2, model.reach_tolerance_m, t2, clamped)) {
    return Status::kUnreachable;
  }
  const T t1 = wrapToPi(std::atan2(y2, x2) - std::atan2(f.p2_m * std::sin(t2), f.p1_m + f.p2_m * std::cos(t2)));
  theta_rad = {t1, t2, wrapToPi(phi - t1 - t2)};
  return clamped ? Status::kReachClamped : Status::kOk;
}

// ---------------------------------------------------------------------------------------------------------
// Jacobians, eq 9–12, 18, 24
// ---------------------------------------------------------------------------------------------------------

/// Finger Jacobian J_θ^u = ∂u/∂θ (eq 9, entries b_ij), 3×3; rows (x m, y m, φ rad), columns θ1..θ3.
template <class T>
inline Mat3<T> jacobianThetaU(const FingerGeometry<T>& f, const ThetaTrig<T>& tr) {
  const T s1 = f.p1_m * tr.s1, s2 = f.p2_m * tr.s12, s3 = f.p3_m * tr.s123;
  const T c1 = f.p1_m * tr.c1, c2 = f.p2_m * tr.c12, c3 = f.p3_m * tr.c123;
  Mat3<T> J{};
  J[0] = {-s1 - s2 - s3, -s2 - s3, -s3};
  J[1] = {c1 + c2 + c3, c2 + c3, c3};
  J[2] = {T(1), T(1), T(1)};
  return J;
}

template <class T>
inline Mat3<T> jacobianThetaU(const FingerGeometry<T>& f, const Vec3<T>& theta_rad) {
  return jacobianThetaU(f, thetaTrig(theta_rad));
}

/// Mechanism Jacobian J_α^u = ∂u/∂α (eq 9, entries a_ij), 3×3. Derived from eq 3–5; the paper's
/// a22 = l2 c12 + l3 c123 − l_p s123 − l_p s123 counts the l_p term twice (typo): the correct
/// a22 = l2 c_α12 + l3 c_α123 − l_p s_α123 is implemented here.
template <class T>
inline Mat3<T> jacobianAlphaU(const MechanismGeometry<T>& m, const ThetaTrig<T>& tr) {
  const T s1 = m.l1_m * tr.s1, s2 = m.l2_m * tr.s12;
  const T c1 = m.l1_m * tr.c1, c2 = m.l2_m * tr.c12;
  const T x3 = -m.l3_m * tr.s123 - m.l_p_m * tr.c123;  // a13
  const T y3 = m.l3_m * tr.c123 - m.l_p_m * tr.s123;   // a23
  Mat3<T> J{};
  J[0] = {-s1 - s2 + x3, -s2 + x3, x3};
  J[1] = {c1 + c2 + y3, c2 + y3, y3};
  J[2] = {T(1), T(1), T(1)};
  return J;
}

/// J_α^u at α; the chained sines and cosines are thetaTrig's (the same sums α1, α1+α2, α1+α2+α3).
template <class T>
inline Mat3<T> jacobianAlphaU(const MechanismGeometry<T>& m, const Vec3<T>& alpha_rad) {
  return jacobianAlphaU(m, thetaTrig(alpha_rad));
}

/// det J_α^u = l1·l2·sin α2 (m²), eq 24. Zero at α2 = 0 or ±180° (mechanism singular).
template <class T>
inline T detJAlphaU(const MechanismGeometry<T>& m, const Vec3<T>& alpha_rad) {
  return m.l1_m * m.l2_m * std::sin(alpha_rad[1]);
}

/// det J_θ^u = p1·p2·sin θ2 (m²). Zero when the PIP joint is straight (θ2 = 0, inside Table 2's range):
/// the finger is then at its reach boundary and J_α^θ (eq 11) does not exist.
template <class T>
inline T detJThetaU(const FingerGeometry<T>& f, const Vec3<T>& theta_rad) {
  return f.p1_m * f.p2_m * std::sin(theta_rad[1]);
}

/// Inverse of a 3×3 matrix by the adjugate. kSingular (and `inv` = 0) when |det| ≤ min_abs_det.
template <class T>
inline Status invert(const Mat3<T>& a, T min_abs_det, Mat3<T>& inv) {
  inv = Mat3<T>{};
  const T c00 = a[1][1] * a[2][2] - a[1][2] * a[2][1];
  const T c01 = a[1][2] * a[2][0] - a[1][0] * a[2][2];
  const T c02 = a[1][0] * a[2][1] - a[1][1] * a[2][0];
  const T det = a[0][0] * c00 + a[0][1] * c01 + a[0][2] * c02;
  if (!(std::fabs(det) > min_abs_det)) return Status::kSingular;
  const T k = T(1) / det;
  inv[0] = {c00 * k, (a[0][2] * a[2][1] - a[0][1] * a[2][2]) * k, (a[0][1] * a[1][2] - a[0][2] * a[1][1]) * k};
  inv[1] = {c01 * k, (a[0][0] * a[2][2] - a[0][2] * a[2][0]) * k, (a[0][2] * a[1][0] - a[0][0] * a[1][2]) * k};
  inv[2] = {c02 * k, (a[0][1] * a[2][0] - a[0][0] * a[2][1]) * k, (a[0][0] * a[1][1] - a[0][1] * a[1][0]) * k};
  return Status::kOk;
}

/// C = A·B
template <class T>
inline Mat3<T> mul(const Mat3<T>& a, const Mat3<T>& b) {
  Mat3<T> c{};
  for (std::size_t i = 0; i < 3; ++i) {
    for (std::size_t j = 0; j < 3; ++j) {
      c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
    }
  }
  return c;
}

/// J_α^θ = (J_θ^u)^{-1} J_α^u (eq 11): θ̇ = J_α^θ α̇. kSingular (and 0) when |det J_θ^u| ≤ min_abs_det_m2.
template <class T>
inline Status jacobianAlphaTheta(const Mat3<T>& J_theta_u, const Mat3<T>& J_alpha_u, T min_abs_det_m2,
                                 Mat3<T>& J_alpha_theta) {
  Mat3<T> inv{};
  const Status s = invert(J_theta_u, min_abs_det_m2, inv);
  J_alpha_theta = s == Status::kOk ? mul(inv, J_alpha_u) : Mat3<T>{};
  return s;
}

/// Mechanism joint torques τ_α (N·m) that balance the planar fingertip wrench F = (f_x N, f_y N, m_z N·m)
/// in {O} at A3: τ_α = (J_α^u)ᵀ F (eq 18).
template <class T>
inline Vec3<T> mechanismTorqueFromWrench(const Mat3<T>& J_alpha_u, const Vec3<T>& O_F_tip) {
  return mulTransposed(J_alpha_u, O_F_tip);
}

/// Finger joint torques τ_θ (N·m) for the same wrench: τ_θ = (J_θ^u)ᵀ F.
template <class T>
inline Vec3<T> fingerTorqueFromWrench(const Mat3<T>& J_theta_u, const Vec3<T>& O_F_tip) {
  return mulTransposed(J_theta_u, O_F_tip);
}

/// Mechanism joint torques from finger joint torques, τ_α = (J_α^θ)ᵀ τ_θ (eq 12).
template <class T>
inline Vec3<T> mechanismTorqueFromFingerTorque(const Mat3<T>& J_alpha_theta, const Vec3<T>& tau_theta_Nm) {
  return mulTransposed(J_alpha_theta, tau_theta_Nm);
}

/// Unit normal of the fingertip pad in {O}: the local y axis of link 3 at angle φ, (−sin φ, cos φ, 0) as a
/// planar wrench direction (m_z = 0). It points dorsally (out of the nail); a force along +n pushes the
/// fingertip towards extension. The strain gauge measures the force component along it.
template <class T>
inline Vec3<T> padNormal(T phi_rad) {
  return {-std::sin(phi_rad), std::cos(phi_rad), T(0)};
}

// ---------------------------------------------------------------------------------------------------------
// Whole-finger computations into Data
// ---------------------------------------------------------------------------------------------------------

namespace detail {
template <class T>
inline bool withinRange(const FingerGeometry<T>& f, const Vec3<T>& theta_rad) {
  // 1e-6 rad slack so that grid points exactly on Table 2's bounds count as inside after a round trip.
  const T slack = T(1e-6) + T(64) * std::numeric_limits<T>::epsilon();
  for (std::size_t i = 0; i < 3; ++i) {
    if (theta_rad[i] < f.theta_min_rad[i] - slack || theta_rad[i] > f.theta_max_rad[i] + slack) return false;
  }
  return true;
}

/// Fills J_theta_u, both determinants, the flags and J_alpha_theta from data.alpha_rad / data.theta_rad.
template <class T>
inline void fillJacobians(const Model<T>& model, Data<T>& d) {
  d.J_theta_u = jacobianThetaU(model.finger, d.theta_rad);
  d.det_J_theta_u = detJThetaU(model.finger, d.theta_rad);
  d.theta_near_singular = std::fabs(std::sin(d.theta_rad[1])) < model.near_singular_sin;
  // Numerically singular: |sin θ2| below ~√eps; J_α^θ then has entries ≳ 1/√eps and is not formed.
  const T min_det = model.finger.p1_m * model.finger.p2_m * std::sqrt(std::numeric_limits<T>::epsilon());
  d.J_alpha_theta_valid =
      jacobianAlphaTheta(d.J_theta_u, d.J_alpha_u, min_det, d.J_alpha_theta) == Status::kOk;
  d.theta_within_range = withinRange(model.finger, d.theta_rad);
}

template <class T>
inline void fillMechanism(const Model<T>& model, Data<T>& d) {
  d.J_alpha_u = jacobianAlphaU(model.mech, d.alpha_rad);
  d.det_J_alpha_u = detJAlphaU(model.mech, d.alpha_rad);
  d.alpha_near_singular = std::fabs(std::sin(d.alpha_rad[1])) < model.near_singular_sin;
}
}  // namespace detail

/// The host cycle for one finger from measured mechanism angles α (rad): θ, u, J_α^u, J_θ^u, J_α^θ,
/// determinants and flags, written into `d`. J_alpha_u, det_J_alpha_u and alpha_near_singular are filled
/// even when the finger pose is unreachable. On kNonFiniteInput everything is reset to 0 (never NaN).
template <class T>
inline Status computeFromAlpha(const Model<T>& model, const Vec3<T>& alpha_rad, Data<T>& d) {
  d = Data<T>{};
  if (!allFinite(alpha_rad)) {
    d.status = Status::kNonFiniteInput;
    return d.status;
  }
  d.alpha_rad = alpha_rad;
  detail::fillMechanism(model, d);
  d.status = thetaFromAlpha(model, alpha_rad, d.theta_rad);
  if (!isUsable(d.status)) return d.status;
  d.O_u_tip = tipPoseFromAlpha(model.mech, alpha_rad);
  detail::fillJacobians(model, d);
  return d.status;
}

/// Same from finger angles θ (rad), e.g. for simulation and design studies: α (eq 6–8), u, Jacobians.
template <class T>
inline Status computeFromTheta(const Model<T>& model, const Vec3<T>& theta_rad, Data<T>& d) {
  d = Data<T>{};
  if (!allFinite(theta_rad)) {
    d.status = Status::kNonFiniteInput;
    return d.status;
  }
  d.theta_rad = theta_rad;
  d.status = alphaFromTheta(model, theta_rad, d.alpha_rad);
  if (!isUsable(d.status)) return d.status;
  d.O_u_tip = tipPoseFromTheta(model.finger, theta_rad);
  detail::fillMechanism(model, d);
  detail::fillJacobians(model, d);
  return d.status;
}

}  // namespace phalanx::glove
