#pragma once
/// RML glove, host side: hand model (five planar finger chains placed in a 3-D hand frame), virtual scene
/// (balls, planes) and the per-cycle force rendering F = b·ẋ + k·x (seeds/000 eq 1) → per-finger fingertip
/// pad-force setpoints for the firmware, with the J^T mapping (eq 18) and the capstan feed-forward (eq 15–16).
///
/// Frames:
///  - {H} hand frame: origin at the middle finger's MCP joint centre, x_H distal along the middle metacarpal,
///    y_H dorsal (out of the back of the hand), z_H = x_H × y_H — towards the thumb on a LEFT hand (the
///    paper's prototype, Fig. 1), towards the little finger on a right hand.
///  - {O_i} finger base frame of finger i (see phalanx/glove/kinematics.h): origin at the finger's first
///    joint (MCP; CMC for the thumb), x_O along the extended finger, y_O dorsal, the finger moves in its
///    x_O–y_O plane. H_R_O = fingerRotation(hand.mounts[i]).
///
/// Force setpoint sign (matches protocol kGlove5Layout): the scalar sent to the firmware is the component of
/// the rendered fingertip force along the pad normal n_pad = y axis of link 3 (angle φ), which points
/// dorsally. POSITIVE = the glove pushes the fingertip towards extension/opening, i.e. resists flexion
/// (touching an object with the finger pad); negative = pushes towards flexion (object on the nail side).
///
/// Real-time contract: GloveScene::render() does not allocate, throw or block. Objects are stored in a
/// fixed-capacity array.
#include <array>
#include <cstddef>
#include <cstdint>

#include "phalanx/glove/capstan.h"
#include "phalanx/glove/kinematics.h"
#include "phalanx/glove/tendon.h"

namespace phalanx::host::glove {

using Vec3d = std::array<double, 3>;
using Mat3d = phalanx::glove::Mat3<double>;
using phalanx::glove::FingerId;
inline constexpr std::size_t kNumFingers = phalanx::glove::kNumFingers;
/// Finger names in FingerId order (summaries, messages).
inline constexpr const char* kFingerNames[kNumFingers] = {"thumb", "index", "middle", "ring", "little"};

/// Maximum active fingertip force of the glove actuators (N), paper §2.2.
inline constexpr double kMaxActiveForce_N = 10.0;

enum class Handedness : std::uint8_t { kLeft = 0, kRight = 1 };

/// Placement of one finger's planar chain on the hand. With ψ = splay_rad and χ = roll_rad:
///   x_O = cos ψ x_H + sin ψ z_H,   y_O = cos χ y_H + sin χ (−sin ψ x_H + cos ψ z_H),   z_O = x_O × y_O.
/// Positive ψ, χ turn the finger towards +z_H.
struct FingerMount {
  Vec3d H_p_base_m{};     ///< origin of {O_i} in {H} (m)
  double splay_rad = 0.0;  ///< fan-out of the finger about y_H
  double roll_rad = 0.0;   ///< rotation about the finger's own long axis (thumb pronation)
};

struct HandModel {
  Handedness side = Handedness::kLeft;
  std::array<phalanx::glove::Model<double>, kNumFingers> fingers{};  ///< indexed by FingerId
  std::array<FingerMount, kNumFingers> mounts{};
};

/// Default adult male hand (hand length 197 mm, the hand Table 2 describes); docs/glove-model.md lists every
/// number and its source. A right hand is the mirror image (z, splay and roll negated).
HandModel defaultHandModel(Handedness side = Handedness::kLeft);

/// H_R_O of a finger mounted at `mount` (columns x_O, y_O, z_O expressed in {H}).
Mat3d fingerRotation(const FingerMount& mount);

/// Penalty contact law parameters of eq 1.
struct ContactMaterial {
  double stiffness_N_per_m = 0.0;  ///< k
  double damping_N_s_per_m = 0.0;  ///< b
};

/// Rigid-feeling object: k = 2000 N/m reaches the 10 N actuator limit at 5 mm penetration; b = 5 N·s/m
/// adds 1 N at a 0.2 m/s finger closing speed (the paper's 1 s close/open maneuver, §4.3). Stiffer values
/// are not useful: the 10 N clamp already caps the force.
inline constexpr ContactMaterial kRigidMaterial{2000.0, 5.0};
/// Soft ball: k = 200 N/m (10 N at 50 mm: squeezable), b = 1 N·s/m.
inline constexpr ContactMaterial kSoftMaterial{200.0, 1.0};
/// Table / wall: same as the rigid ball.
inline constexpr ContactMaterial kWallMaterial{2000.0, 5.0};

enum class ObjectKind : std::uint8_t { kBall = 0, kPlane = 1 };

struct VirtualObject {
  ObjectKind kind = ObjectKind::kBall;
  Vec3d H_p_m{};               ///< ball: centre; plane: any point of the surface ({H}, m)
  Vec3d H_n{0.0, 1.0, 0.0};    ///< plane: outward unit normal (points into free space); unused for balls
  double radius_m = 0.0;       ///< ball radius (m)
  ContactMaterial material{};
};

/// Default ball radius: 35 mm (a 70 mm ball, tennis-ball size, a typical power-grasp object).
inline constexpr double kDefaultBallRadius_m = 0.035;

VirtualObject rigidBall(const Vec3d& H_center_m, double radius_m = kDefaultBallRadius_m,
                        ContactMaterial material = kRigidMaterial);
VirtualObject softBall(const Vec3d& H_center_m, double radius_m = kDefaultBallRadius_m,
                       ContactMaterial material = kSoftMaterial);
/// Half-space bounded by a plane; `H_normal` need not be unit length (it is normalised).
VirtualObject plane(const Vec3d& H_point_m, const Vec3d& H_normal, ContactMaterial material = kWallMaterial);

struct SceneConfig {
  double max_force_N = kMaxActiveForce_N;  ///< clamp of the rendered force magnitude (device capability)
  /// Fingertip proxy: a sphere of this radius centred on the fingertip point A3 (0 = point proxy at A3).
  double tip_radius_m = 0.0;
  double mu = phalanx::glove::kMuLubricated<double>;                ///< tendon friction, §4.2
  double gamma_c_rad = phalanx::glove::kGammaConstDefault_rad<double>;  ///< constant wrap, eq 16
  /// Below this pad-normal speed the sliding direction (and so the capstan factor) is unknown (static
  /// friction); the feed-forward then uses no friction factor. 5 mm/s ≈ 2.5 % of the §4.3 closing speed.
  double slide_deadband_m_per_s = 0.005;
  /// Tendon tension at link 3 per newton of pad force: 1/c of the shared tendon model (glove/tendon.h).
  double tendon_tension_per_pad_force = 1.0 / phalanx::glove::TendonDesign<double>{}.pad_transmission;
};

/// Per-cycle input of one finger, from telemetry.
struct FingerInput {
  Vec3d alpha_rad{};             ///< mechanism angles α1..α3 (Hall sensors)
  Vec3d alpha_dot_rad_per_s{};   ///< their rates
};

enum class FingerStatus : std::uint8_t {
  kOk = 0,
  kNonFiniteAngle = 1,  ///< NaN/Inf in α: setpoint 0
  kNonFiniteRate = 2,   ///< NaN/Inf in α̇: setpoint 0
  kUnreachable = 3,     ///< α gives a fingertip pose the finger cannot reach: setpoint 0
};

struct FingerOutput {
  /// → firmware: pad-normal fingertip force (N), + = towards extension (resists flexion), |·| ≤ max_force_N.
  double force_setpoint_N = 0.0;
  FingerStatus status = FingerStatus::kNonFiniteAngle;
  bool in_contact = false;      ///< penetrating at least one object
  bool force_limited = false;   ///< rendered force magnitude was clamped to max_force_N
  bool reach_clamped = false;   ///< kinematics returned kReachClamped (within reach tolerance)
  bool near_singular = false;   ///< eq 24 margin: |sin α2| below Model::near_singular_sin
  int contact_object = -1;      ///< index of the deepest-penetrated object, −1 when none
  double penetration_m = 0.0;               ///< x ≥ 0 into contact_object
  double penetration_rate_m_per_s = 0.0;    ///< ẋ into contact_object (+ = going deeper)
  double normal_force_N = 0.0;              ///< |rendered force| after the clamp, ≥ 0
  Vec3d H_p_tip_m{};            ///< fingertip point A3 in {H}
  Vec3d H_v_tip_m_per_s{};      ///< its velocity in {H}
  Vec3d H_F_tip_N{};            ///< rendered force on the fingertip in {H} (sum over objects, clamped)
  Vec3d theta_rad{};            ///< finger joint angles from α
  Vec3d tau_alpha_Nm{};         ///< mechanism joint torques for the commanded pad force, eq 18
  phalanx::glove::Tendon tendon = phalanx::glove::Tendon::kRelease;  ///< tendon that carries the setpoint
  double tip_tension_N = 0.0;    ///< tendon tension needed at link 3
  double spool_tension_N = 0.0;  ///< spool-side tension incl. capstan friction (feed-forward)
};

using RenderInput = std::array<FingerInput, kNumFingers>;
using RenderOutput = std::array<FingerOutput, kNumFingers>;

/// Hand + scene + preallocated kinematic workspaces. Construct and add objects at start-up; call render()
/// once per host cycle.
class GloveScene {
 public:
  static constexpr std::size_t kMaxObjects = 16;

  explicit GloveScene(const HandModel& hand = defaultHandModel(), const SceneConfig& config = SceneConfig{});

  /// Adds an object; false (scene unchanged) when full or when the object is invalid (non-finite numbers,
  /// radius ≤ 0, k < 0, b < 0, zero plane normal).
  bool addObject(const VirtualObject& object);
  void clearObjects() { object_count_ = 0; }
  std::size_t objectCount() const { return object_count_; }
  const VirtualObject& object(std::size_t i) const { return objects_[i]; }

  /// Stiffness limit applied to every object's k in render() (N/m; 0 = none): the host renders at its own period
  /// T, and the rendering loop is stable only up to a k·T product (GloveControllerConfig). A negative or
  /// non-finite value is refused (false) and leaves the limit as it was.
  bool setStiffnessLimit(double k_max_N_per_m);
  /// Object i's stiffness as rendered: min(k, limit).
  double renderedStiffness(std::size_t i) const;

  /// One host cycle for all five fingers: θ from α, Jacobians, fingertip pose/velocity in {H}, contact
  /// forces (eq 1), pad-normal setpoints, τ_α = (J_α^u)ᵀ F (eq 18), capstan feed-forward (eq 15–16).
  /// No allocation.
  void render(const RenderInput& in, RenderOutput& out);

  const HandModel& hand() const { return hand_; }
  const SceneConfig& config() const { return config_; }
  /// Kinematic workspace of finger i after the last render().
  const phalanx::glove::Data<double>& data(std::size_t i) const { return data_[i]; }
  const Mat3d& rotation(std::size_t i) const { return H_R_O_[i]; }

 private:
  void renderFinger(std::size_t i, const FingerInput& in, FingerOutput& out);

  HandModel hand_;
  SceneConfig config_;
  std::array<Mat3d, kNumFingers> H_R_O_{};
  std::array<phalanx::glove::CapstanModel<double>, kNumFingers> capstan_{};
  std::array<phalanx::glove::Data<double>, kNumFingers> data_{};
  std::array<VirtualObject, kMaxObjects> objects_{};
  std::size_t object_count_ = 0;
  double stiffness_limit_N_per_m_ = 0.0;
};

/// The daemon's named scenes (`glove.scene`: none | rigid-ball | soft-ball | wall).
enum class DemoScene : std::uint8_t { kNone = 0, kRigidBall = 1, kSoftBall = 2, kWall = 3 };

/// Replaces the objects of `scene` with a demo scene, placed for `hand`'s side: a ball under the palm at
/// H (34, −67, 0) mm that the closing fingertip pads meet, or a table 40 mm below the MCP joints.
void loadDemoScene(GloveScene& scene, DemoScene which);

}  // namespace phalanx::host::glove
