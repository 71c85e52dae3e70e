#pragma once
/// Twin-Pantograph haptic pen: kinematics (Stocco, Salcudean & Sassani, seeds/004 §V–VI, Fig. 11, 16).
///
/// Header-only, freestanding C++17 (no heap, no exceptions, no iostream), templated on the scalar type:
/// `double` on the host, `float` on the microcontroller. A const `Model<T>` (geometry, Table VIII at 20 cm)
/// and a preallocated `Data<T>` workspace that `computeForward()` writes into.
///
/// Frames and conventions (docs/pen-model.md has the full description and the reading of every length):
///  - Base frame {B}: origin on the device's centre line midway between the two waist axes; x_B lateral (the
///    paper's i axis, the 16 cm workspace direction), y_B up along the pen at home (j, the passive roll axis),
///    z_B away from the base towards the workspace (k; the workspace centre is at z = 20 cm, Table VIII).
///  - Two pantographs, p = 0 bottom (joints q1, q2, q3 — it holds the pencil TIP), p = 1 top (q4, q5, q6 —
///    it holds the eraser end). Each is a symmetric five-bar in its own plane: two shoulder motors on the waist
///    axis, l1 apart; upper arms l2; forearms l3 meeting at the tip (a universal joint holding one pen end).
///  - The waist axis of pantograph p is the line {y = y_waist_p, z = 0} parallel to x_B. Waist angle q_w turns
///    the five-bar plane about it. In-plane coordinates (u, v): u along x_B, v the reach from the waist axis.
///    Tip in {B}: (u, y_waist + v·sin q_w, v·cos q_w).
///  - Shoulder angles θa (shoulder at u = −l1/2) and θb (u = +l1/2) are measured in the plane from +u towards +v;
///    the elbows point outwards (θa > the tip direction, θb < it), the tip is the far (+v) circle intersection.
///  - Joint vector q = (q_w,B, θa,B, θb,B, q_w,T, θa,T, θb,T) = the paper's (q1, q2, q3, q4, q5, q6) (§V).
///  - Pen ends: the universal-joint centres c ∓ l6·a. Table VIII's l6 is read as the distance from the pen centre
///    to EACH universal joint, so the joints are 2·l6 = 14 cm apart (docs/pen-model.md §"Reading the lengths";
///    endOffset()/penLength() are the one definition every user calls).
///  - Pen pose: centre c (m) and axis a (unit, bottom → top end). a = Rz(θz)·Rx(θx)·y_B =
///    (−sin θz cos θx, cos θz cos θx, sin θx); θx, θz are the two actuated rotations of Table X, roll about a
///    is passive.
///  - Jacobians J[row][col]: rows (x, y, z) of the tip in {B}, columns (q_w, θa, θb) of that pantograph.
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <limits>

namespace phalanx::pen {

template <class T>
using Vec3 = std::array<T, 3>;
/// Row-major 3×3 matrix, M[row][col].
template <class T>
using Mat3 = std::array<std::array<T, 3>, 3>;
inline constexpr std::size_t kNumJoints = 6;
inline constexpr std::size_t kNumPantographs = 2;
template <class T>
using JointVec = std::array<T, kNumJoints>;

inline constexpr std::size_t kBottom = 0;  ///< pantograph holding the pencil tip, joints q1..q3
inline constexpr std::size_t kTop = 1;     ///< pantograph holding the eraser end, joints q4..q6

template <class T>
inline constexpr T kPi = T(3.14159265358979323846);

template <class T>
constexpr T degToRad(T deg) {
  return deg * (kPi<T> / T(180));
}

/// Result of a kinematic computation. Faults 1..15, "limit active" (usable) from 16.
enum class Status : std::uint8_t {
  kOk = 0,
  kNonFiniteInput = 1,    ///< NaN/Inf input: outputs left at 0
  kUnreachable = 2,       ///< five-bar loop cannot close / point out of reach: outputs left at 0
  kSingular = 3,          ///< a pantograph Jacobian is numerically singular (forearms or arms aligned)
  kEndsInconsistent = 4,  ///< the two measured pen ends are not one pen length apart (sensor fault)
  kNearSingular = 16,     ///< usable, but a singularity margin is below Model::near_singular_sin
};

constexpr bool isUsable(Status s) { return s == Status::kOk || s == Status::kNearSingular; }

/// Bits of Data::near_singular (one group of four per pantograph: bit + 4·p), §V's singular configurations.
enum SingularBit : std::uint8_t {
  kForearmsAligned = 1u << 0,  ///< (i) Fig. 12: the two forearms collinear (five-bar type-II singularity)
  kArmStretched = 1u << 1,     ///< (i)/(iii) an upper arm and its forearm collinear: workspace limit
  kTipOnWaistAxis = 1u << 2,   ///< (ii) the tip is near its own waist axis (the waist moves it no more)
  kPenAlongForearm = 1u << 3,  ///< (iv) the pen axis aligns with a forearm (spherical-wrist singularity)
};

/// One five-bar pantograph on its waist axis.
template <class T>
struct PantographGeometry {
  T l1_m{};          ///< distance between the two shoulder axes (on the waist axis), Table VIII l1
  T l2_m{};          ///< upper arm (shoulder → elbow), Table VIII l2
  T l3_m{};          ///< forearm (elbow → tip universal joint), Table VIII l3
  T y_waist_m{};     ///< height of the waist axis in {B}: ∓ l4/2
};

template <class T>
struct Model {
  std::array<PantographGeometry<T>, kNumPantographs> pantograph{};
  /// Table VIII l6: distance from the pen centre to each universal-joint centre (the joints are 2·l6 apart).
  /// Use endOffset()/penLength(), never l6 directly, to place the ends.
  T l6_m{};
  /// Encoder: 4000 counts per turn (§VI) on all six joints; angle = q_home + sign·counts·2π/4000.
  T counts_per_rev = T(4000);
  JointVec<T> q_home_rad{};       ///< joint angles at the home pose (x = y = 0, z = 20 cm, no rotation)
  JointVec<T> encoder_sign{T(1), T(1), T(1), T(1), T(1), T(1)};
  Vec3<T> home_centre_m{};        ///< (0, 0, 0.20)
  /// A singularity margin (a sine, see SingularBit) below this raises the bit. 0.1 ≈ 5.7°: 5° is the
  /// universal-joint bend margin of §V (±85° constraint); the same angle is used for the other three.
  T near_singular_sin = T(0.1);
  /// Tip closer than this to its waist axis raises kTipOnWaistAxis (10 % of the 20 cm reach).
  T near_waist_axis_m = T(0.02);
  /// | |p_top − p_bottom| − 2·l6 | beyond this is a sensor fault (kEndsInconsistent). 2 mm ≈ 10 encoder counts
  /// of tip motion (Table X: 142–314 µm per count).
  T ends_tolerance_m = T(0.002);
};

/// Pen pose: 3 translations + 2 rotations (Table X axes); roll is passive.
template <class T>
struct PenPose {
  Vec3<T> centre_m{};
  T theta_x_rad{};
  T theta_z_rad{};
};

/// Per-pantograph results of computeForward().
template <class T>
struct PantographData {
  Vec3<T> q_rad{};              ///< (q_w, θa, θb)
  T u_m{}, v_m{};               ///< tip in the five-bar plane
  T elbow_a_u{}, elbow_a_v{};   ///< elbows in the plane (m)
  T elbow_b_u{}, elbow_b_v{};
  Vec3<T> B_p_tip{};            ///< tip (universal-joint centre) in {B}
  Mat3<T> J{};                  ///< ∂p_tip/∂q (m/rad), 3×3
  T det_J{};                    ///< det J (m³)
  std::array<Vec3<T>, 2> B_forearm_dir{};  ///< unit forearm directions (elbow → tip) in {B}
  T forearms_sin{};             ///< |sin| of the angle between the two forearms (Fig. 12a)
  T arm_a_sin{}, arm_b_sin{};   ///< |sin| of each elbow angle (upper arm vs forearm)
  T tip_to_waist_m{};           ///< v: distance of the tip from its waist axis
  T pen_forearm_sin{};          ///< min over its two forearms of |sin(pen axis, forearm)|
};

/// Workspace written by computeForward(); preallocate once, reuse every cycle.
template <class T>
struct Data {
  JointVec<T> q_rad{};
  std::array<PantographData<T>, kNumPantographs> pantograph{};
  Vec3<T> B_p_centre{};   ///< pen centre (midpoint of the two ends)
  Vec3<T> B_axis{};       ///< unit pen axis, bottom → top
  T length_m{};           ///< measured |p_top − p_bottom|
  PenPose<T> pose{};
  T min_margin_sin{};     ///< smallest of all sine margins (forearms, arms, pen–forearm)
  std::uint8_t near_singular = 0;  ///< SingularBit << (4·p)
  Status status = Status::kNonFiniteInput;
};

// ---------------------------------------------------------------------------------------------------------
// Small vector helpers
// ---------------------------------------------------------------------------------------------------------

template <class T>
inline Vec3<T> cross(const Vec3<T>& a, const Vec3<T>& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
template <class T>
inline T dot(const Vec3<T>& a, const Vec3<T>& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
template <class T>
inline T norm(const Vec3<T>& a) {
  return std::sqrt(dot(a, a));
}
/// y = Mᵀ·x
template <class T>
inline Vec3<T> mulTransposed(const Mat3<T>& m, const Vec3<T>& x) {
  return {m[0][0] * x[0] + m[1][0] * x[1] + m[2][0] * x[2], m[0][1] * x[0] + m[1][1] * x[1] + m[2][1] * x[2],
          m[0][2] * x[0] + m[1][2] * x[1] + m[2][2] * x[2]};
}
/// y = M·x
template <class T>
inline Vec3<T> mul(const Mat3<T>& m, const Vec3<T>& x) {
  return {m[0][0] * x[0] + m[0][1] * x[1] + m[0][2] * x[2], m[1][0] * x[0] + m[1][1] * x[1] + m[1][2] * x[2],
          m[2][0] * x[0] + m[2][1] * x[1] + m[2][2] * x[2]};
}
template <class T>
inline T det3(const Mat3<T>& m) {
  return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
         m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}
template <class T>
inline bool allFinite(const Vec3<T>& v) {
  return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

/// Pen axis from the two actuated rotations: a = Rz(θz)·Rx(θx)·y_B.
template <class T>
inline Vec3<T> penAxis(T theta_x_rad, T theta_z_rad) {
  const T cx = std::cos(theta_x_rad);
  return {-std::sin(theta_z_rad) * cx, std::cos(theta_z_rad) * cx, std::sin(theta_x_rad)};
}

/// Signed position of pen end `end` along the axis from the centre: −l6 (kBottom, pencil tip), +l6 (kTop,
/// eraser). THE reading of Table VIII's l6 (centre → universal joint, docs/pen-model.md); the kinematics, the
/// plant, the scene and the design tools (host/src/design/pen_gii.cpp) all place the ends through this.
template <class T>
constexpr T endOffset(std::size_t end, T l6) {
  return end == kBottom ? -l6 : l6;
}

/// Distance between the two universal-joint centres: 2·l6.
template <class T>
constexpr T penLength(const Model<T>& model) {
  return T(2) * model.l6_m;
}

/// Pen end `end` of a pen with centre c and unit axis a: c + endOffset(end, l6)·a.
template <class T>
inline Vec3<T> penEnd(std::size_t end, T l6, const Vec3<T>& centre, const Vec3<T>& axis) {
  const T h = endOffset(end, l6);
  return {centre[0] + h * axis[0], centre[1] + h * axis[1], centre[2] + h * axis[2]};
}

/// The two pen ends (universal-joint centres) of a pose: bottom = c − l6·a, top = c + l6·a.
template <class T>
inline void penEnds(const Model<T>& model, const PenPose<T>& pose, Vec3<T>& B_p_bottom, Vec3<T>& B_p_top) {
  const Vec3<T> a = penAxis(pose.theta_x_rad, pose.theta_z_rad);
  B_p_bottom = penEnd(kBottom, model.l6_m, pose.centre_m, a);
  B_p_top = penEnd(kTop, model.l6_m, pose.centre_m, a);
}

// ---------------------------------------------------------------------------------------------------------
// One pantograph
// ---------------------------------------------------------------------------------------------------------

/// Forward kinematics + 3×3 Jacobian + singularity margins of one pantograph (writes everything in `d` except
/// pen_forearm_sin). Five-bar closure: |P − E_a| = |P − E_b| = l3 with E_a = (−l1/2 + l2 cos θa, l2 sin θa),
/// E_b = (l1/2 + l2 cos θb, l2 sin θb); P is the far (+v) intersection. Differentiating the closure,
/// [r_aᵀ; r_bᵀ]·Ṗ = diag(r_a·t_a, r_b·t_b)·θ̇ with r = P − E, t = ∂E/∂θ; the waist adds ∂p/∂q_w = (0, v cos q_w,
/// −v sin q_w).
template <class T>
inline Status pantographForward(const PantographGeometry<T>& g, const Vec3<T>& q_rad, PantographData<T>& d) {
  d = PantographData<T>{};
  if (!allFinite(q_rad)) return Status::kNonFiniteInput;
  d.q_rad = q_rad;
  const T half = T(0.5) * g.l1_m;
  const T ca = std::cos(q_rad[1]), sa = std::sin(q_rad[1]);
  const T cb = std::cos(q_rad[2]), sb = std::sin(q_rad[2]);
  const T eau = -half + g.l2_m * ca, eav = g.l2_m * sa;
  const T ebu = half + g.l2_m * cb, ebv = g.l2_m * sb;
  const T du = ebu - eau, dv = ebv - eav;
  const T dist2 = du * du + dv * dv;
  const T h2 = g.l3_m * g.l3_m - T(0.25) * dist2;
  if (!(dist2 > T(0)) || !(h2 >= T(0))) return Status::kUnreachable;
  const T dist = std::sqrt(dist2);
  const T h = std::sqrt(h2);
  // n = +90° rotation of the unit elbow-to-elbow vector: points to +v for the outward-elbow assembly.
  const T u = T(0.5) * (eau + ebu) - h * dv / dist;
  const T v = T(0.5) * (eav + ebv) + h * du / dist;
  d.u_m = u;
  d.v_m = v;
  d.elbow_a_u = eau;
  d.elbow_a_v = eav;
  d.elbow_b_u = ebu;
  d.elbow_b_v = ebv;
  const T cw = std::cos(q_rad[0]), sw = std::sin(q_rad[0]);
  d.B_p_tip = {u, g.y_waist_m + v * sw, v * cw};

  // Five-bar Jacobian ∂(u, v)/∂(θa, θb).
  const T rau = u - eau, rav = v - eav;  // forearm a, |r_a| = l3
  const T rbu = u - ebu, rbv = v - ebv;
  const T det_a = rau * rbv - rav * rbu;  // r_a × r_b
  const T ka = g.l2_m * (-sa * rau + ca * rav);  // r_a · t_a = (E_a − S_a) × r_a
  const T kb = g.l2_m * (-sb * rbu + cb * rbv);
  const T l3sq = g.l3_m * g.l3_m;
  d.forearms_sin = std::fabs(det_a) / l3sq;
  d.arm_a_sin = std::fabs(ka) / (g.l2_m * g.l3_m);
  d.arm_b_sin = std::fabs(kb) / (g.l2_m * g.l3_m);
  d.tip_to_waist_m = v;
  const T inv_l3 = T(1) / g.l3_m;
  d.B_forearm_dir[0] = {rau * inv_l3, rav * inv_l3 * sw, rav * inv_l3 * cw};
  d.B_forearm_dir[1] = {rbu * inv_l3, rbv * inv_l3 * sw, rbv * inv_l3 * cw};
  // A numerically zero determinant: the forearms are aligned and the tip Jacobian does not exist.
  if (!(std::fabs(det_a) > l3sq * T(64) * std::numeric_limits<T>::epsilon())) return Status::kSingular;
  const T inv = T(1) / det_a;
  const T j_ua = ka * inv * rbv, j_va = -ka * inv * rbu;
  const T j_ub = -kb * inv * rav, j_vb = kb * inv * rau;
  d.J = {{{T(0), j_ua, j_ub}, {v * cw, sw * j_va, sw * j_vb}, {-v * sw, cw * j_va, cw * j_vb}}};
  d.det_J = det3(d.J);
  return Status::kOk;
}

/// Inverse kinematics of one pantograph: tip in {B} → (q_w, θa, θb), outward-elbow branch.
template <class T>
inline Status pantographInverse(const PantographGeometry<T>& g, const Vec3<T>& B_p_tip, Vec3<T>& q_rad) {
  q_rad = {T(0), T(0), T(0)};
  if (!allFinite(B_p_tip)) return Status::kNonFiniteInput;
  const T dy = B_p_tip[1] - g.y_waist_m;
  const T v = std::sqrt(dy * dy + B_p_tip[2] * B_p_tip[2]);
  const T u = B_p_tip[0];
  const T half = T(0.5) * g.l1_m;
  Vec3<T> q{std::atan2(dy, B_p_tip[2]), T(0), T(0)};
  for (int side = 0; side < 2; ++side) {
    const T ru = u - (side == 0 ? -half : half);
    const T rho2 = ru * ru + v * v;
    const T rho = std::sqrt(rho2);
    if (!(rho > T(0))) return Status::kUnreachable;
    const T c = (g.l2_m * g.l2_m + rho2 - g.l3_m * g.l3_m) / (T(2) * g.l2_m * rho);
    if (!(c >= T(-1) && c <= T(1))) return Status::kUnreachable;
    const T phi = std::atan2(v, ru);
    const T gamma = std::acos(c);
    q[side + 1] = side == 0 ? phi + gamma : phi - gamma;  // elbows outwards
  }
  q_rad = q;
  return Status::kOk;
}

// ---------------------------------------------------------------------------------------------------------
// Whole device
// ---------------------------------------------------------------------------------------------------------

/// Joint angles from the six encoder counts (counts relative to the home pose, where the index pulse zeroes
/// them): q_i = q_home_i + sign_i·counts_i·2π/4000.
template <class T>
inline JointVec<T> anglesFromCounts(const Model<T>& model, const std::array<std::int32_t, kNumJoints>& counts) {
  JointVec<T> q{};
  const T rad_per_count = T(2) * kPi<T> / model.counts_per_rev;
  for (std::size_t i = 0; i < kNumJoints; ++i) {
    q[i] = model.q_home_rad[i] + model.encoder_sign[i] * static_cast<T>(counts[i]) * rad_per_count;
  }
  return q;
}

/// Encoder counts (rounded to the nearest count) of joint angles; the inverse of anglesFromCounts.
template <class T>
inline std::array<std::int32_t, kNumJoints> countsFromAngles(const Model<T>& model, const JointVec<T>& q_rad) {
  std::array<std::int32_t, kNumJoints> c{};
  const T counts_per_rad = model.counts_per_rev / (T(2) * kPi<T>);
  for (std::size_t i = 0; i < kNumJoints; ++i) {
    c[i] = static_cast<std::int32_t>(
        std::lround((q_rad[i] - model.q_home_rad[i]) * model.encoder_sign[i] * counts_per_rad));
  }
  return c;
}

/// The pen's two ends from the six joint angles, and the measured pen length |p_top − p_bottom| (Data::length_m):
/// the first half of computeForward, and all the firmware's rigid-pen encoder watch needs (apps/pantograph.h).
/// kOk when the ends are one pen length (2·l6) apart within Model::ends_tolerance_m, kEndsInconsistent when not,
/// or the first pantograph's failure (kUnreachable: its five-bar cannot close; kSingular: its Jacobian does not
/// exist — its tip is still written).
template <class T>
inline Status computeEnds(const Model<T>& model, const JointVec<T>& q_rad, Data<T>& d) {
  d.q_rad = q_rad;
  d.near_singular = 0;
  for (std::size_t p = 0; p < kNumPantographs; ++p) {
    const Vec3<T> qp{q_rad[3 * p], q_rad[3 * p + 1], q_rad[3 * p + 2]};
    const Status s = pantographForward(model.pantograph[p], qp, d.pantograph[p]);
    if (s != Status::kOk) {
      d.status = s;
      return s;
    }
  }
  const Vec3<T>& pb = d.pantograph[kBottom].B_p_tip;
  const Vec3<T>& pt = d.pantograph[kTop].B_p_tip;
  d.length_m = norm(Vec3<T>{pt[0] - pb[0], pt[1] - pb[1], pt[2] - pb[2]});
  d.status = std::fabs(d.length_m - penLength(model)) <= model.ends_tolerance_m ? Status::kOk : Status::kEndsInconsistent;
  return d.status;
}

/// Forward kinematics of the whole device from the six joint angles: both tips, both Jacobians, the pen pose
/// (centre, axis, θx, θz), and §V's singularity margins. Status kEndsInconsistent when the tips are not one
/// pen length (2·l6) apart (Model::ends_tolerance_m): the outputs are then still filled but must not be used to
/// command force.
template <class T>
inline Status computeForward(const Model<T>& model, const JointVec<T>& q_rad, Data<T>& d) {
  const Status ends = computeEnds(model, q_rad, d);
  if (ends != Status::kOk && ends != Status::kEndsInconsistent) return ends;
  if (!(d.length_m > T(0))) {
    d.status = Status::kEndsInconsistent;
    return d.status;
  }
  const Vec3<T>& pb = d.pantograph[kBottom].B_p_tip;
  const Vec3<T>& pt = d.pantograph[kTop].B_p_tip;
  const Vec3<T> diff{pt[0] - pb[0], pt[1] - pb[1], pt[2] - pb[2]};
  const T inv_len = T(1) / d.length_m;
  d.B_axis = {diff[0] * inv_len, diff[1] * inv_len, diff[2] * inv_len};
  d.B_p_centre = {T(0.5) * (pb[0] + pt[0]), T(0.5) * (pb[1] + pt[1]), T(0.5) * (pb[2] + pt[2])};
  d.pose.centre_m = d.B_p_centre;
  d.pose.theta_x_rad = std::asin(d.B_axis[2] > T(1) ? T(1) : (d.B_axis[2] < T(-1) ? T(-1) : d.B_axis[2]));
  d.pose.theta_z_rad = std::atan2(-d.B_axis[0], d.B_axis[1]);

  T min_sin = T(1);
  for (std::size_t p = 0; p < kNumPantographs; ++p) {
    PantographData<T>& pd = d.pantograph[p];
    const T s0 = norm(cross(d.B_axis, pd.B_forearm_dir[0]));
    const T s1 = norm(cross(d.B_axis, pd.B_forearm_dir[1]));
    pd.pen_forearm_sin = s0 < s1 ? s0 : s1;
    std::uint8_t bits = 0;
    if (pd.forearms_sin < model.near_singular_sin) bits |= kForearmsAligned;
    if (pd.arm_a_sin < model.near_singular_sin || pd.arm_b_sin < model.near_singular_sin) bits |= kArmStretched;
    if (pd.tip_to_waist_m < model.near_waist_axis_m) bits |= kTipOnWaistAxis;
    if (pd.pen_forearm_sin < model.near_singular_sin) bits |= kPenAlongForearm;
    d.near_singular = static_cast<std::uint8_t>(d.near_singular | (bits << (4 * p)));
    const T m = std::fmin(std::fmin(pd.forearms_sin, pd.pen_forearm_sin), std::fmin(pd.arm_a_sin, pd.arm_b_sin));
    min_sin = m < min_sin ? m : min_sin;
  }
  d.min_margin_sin = min_sin;
  if (ends == Status::kEndsInconsistent) {
    d.status = ends;
  } else {
    d.status = d.near_singular != 0 ? Status::kNearSingular : Status::kOk;
  }
  return d.status;
}

/// Joint angles of a pen pose (both pantographs' inverse kinematics).
template <class T>
inline Status computeInverse(const Model<T>& model, const PenPose<T>& pose, JointVec<T>& q_rad) {
  q_rad = JointVec<T>{};
  if (!allFinite(pose.centre_m) || !std::isfinite(pose.theta_x_rad) || !std::isfinite(pose.theta_z_rad)) {
    return Status::kNonFiniteInput;
  }
  std::array<Vec3<T>, kNumPantographs> ends{};
  penEnds(model, pose, ends[kBottom], ends[kTop]);
  JointVec<T> q{};
  for (std::size_t p = 0; p < kNumPantographs; ++p) {
    Vec3<T> qp{};
    const Status s = pantographInverse(model.pantograph[p], ends[p], qp);
    if (s != Status::kOk) return s;
    for (std::size_t i = 0; i < 3; ++i) q[3 * p + i] = qp[i];
  }
  q_rad = q;
  return Status::kOk;
}

// ---------------------------------------------------------------------------------------------------------
// Default geometry
// ---------------------------------------------------------------------------------------------------------

/// Lengths of a Twin-Pantograph (Table VII/VIII symbols, metres) and the home pose's centre depth.
template <class T>
struct Geometry {
  T l1_m{}, l2_m{}, l3_m{};  ///< shoulder spacing, upper arm, forearm (both pantographs alike)
  T l4_m{};                  ///< distance between the two waist axes
  T l6_m{};                  ///< pen centre → each universal joint (pen length 2·l6)
  T home_z_m{};              ///< home = workspace centre: (0, 0, home_z), no rotation (§VI: 20 cm)
};

/// The model of a geometry; q_home by inverse kinematics of the home pose. Status kOk, or why the geometry
/// cannot be a pen (kNonFiniteInput: a length not finite or ≤ 0; kUnreachable: home not reachable; kSingular /
/// kEndsInconsistent: home pose singular). `out` is written only on kOk.
template <class T>
inline Status makeModel(const Geometry<T>& g, Model<T>& out) {
  for (T v : {g.l1_m, g.l2_m, g.l3_m, g.l4_m, g.l6_m, g.home_z_m}) {
    if (!std::isfinite(v) || !(v > T(0))) return Status::kNonFiniteInput;
  }
  Model<T> m{};
  for (std::size_t p = 0; p < kNumPantographs; ++p) {
    m.pantograph[p].l1_m = g.l1_m;
    m.pantograph[p].l2_m = g.l2_m;
    m.pantograph[p].l3_m = g.l3_m;
    m.pantograph[p].y_waist_m = (p == kBottom ? T(-0.5) : T(0.5)) * g.l4_m;
  }
  m.l6_m = g.l6_m;
  m.home_centre_m = {T(0), T(0), g.home_z_m};
  PenPose<T> home{};
  home.centre_m = m.home_centre_m;
  const Status si = computeInverse(m, home, m.q_home_rad);
  if (si != Status::kOk) return si;
  Data<T> d{};
  const Status sf = computeForward(m, m.q_home_rad, d);
  if (!isUsable(sf)) return sf;
  out = m;
  return Status::kOk;
}

/// The 20 cm prototype (§VI, Fig. 16): Table VIII row "20 cm": l1 = 2.4, l2 = 14.5, l3 = 20.0, l6 = 7.0 cm,
/// l4 = 8.0 cm (fixed, §VI). docs/pen-model.md §"Reading the lengths" explains each assignment.
template <class T>
inline Geometry<T> defaultGeometry() {
  const T cm = T(0.01);
  return {T(2.4) * cm, T(14.5) * cm, T(20.0) * cm, T(8.0) * cm, T(7.0) * cm, T(20.0) * cm};
}

template <class T>
inline Model<T> defaultModel() {
  Model<T> m{};
  makeModel(defaultGeometry<T>(), m);  // the default geometry reaches home by construction (tested)
  return m;
}

}  // namespace phalanx::pen
