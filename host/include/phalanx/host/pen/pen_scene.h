#pragma once
/// Virtual environment of the haptic pen (seeds/004 §VI, Fig. 17): a virtual pencil writing on the inside of a
/// stiff bounding box, a compliant button on the box floor that clicks (and erases the pencil marks), and
/// gravity compensation of the pen's unbalanced weight.
///
/// Rendering is PD+B per pen END (the decoupled control of Fig. 18: the tip feels a wall while the eraser end
/// stays free): for each end and each wall it penetrates by δ > 0 with normal velocity v_n (> 0 leaving the wall)
///   F_n = max(0, K·δ − B·v_n)            spring–damper wall, pushes only
///   F_n += −B_brake·v_n (v_n < 0)        braking pulse [22], for ONE control period at contact onset
/// End velocities are low-pass filtered finite differences of the encoder-derived end positions (Table X note).
/// No allocation after construction.
#include <array>
#include <cstdint>

#include "phalanx/host/pen/force_split.h"
#include "phalanx/pen/dynamics.h"
#include "phalanx/pen/kinematics.h"

namespace phalanx::host::pen {

/// One wall's PD+B gains (SI).
struct WallGains {
  double stiffness_N_per_m = 0.0;
  double damping_N_s_per_m = 0.0;
  double brake_N_s_per_m = 0.0;
};

struct PenSceneConfig {
  bool box = true;
  /// Free space inside the box (m, {B}); the floor is y = box_min[1]; the box is open at the top. The floor is
  /// 2 cm below the tip of the pen at home (tip at y = −l6 = −7 cm).
  Vec3d box_min{-0.05, -0.09, 0.16};
  Vec3d box_max{0.05, 1.0, 0.24};
  /// §VI stiff box: 3 N/cm, 0.05 N·s/cm, 6 N·s/cm horizontal (x, z walls); 2.1 N/cm, 0.02 N·s/cm, 3 N·s/cm vertical.
  WallGains horizontal{300.0, 5.0, 600.0};
  WallGains vertical{210.0, 2.0, 300.0};
  bool braking = true;
  /// Beyond the paper: limit the braking pulse to the impulse that brings each contacting end to rest along its
  /// wall normal, using the measured mass matrix D (eq 29) — a larger pulse reverses the end's velocity, i.e.
  /// the "brake" throws the pen back out of the wall and generates energy (docs/pen-plant.md §"Braking pulse").
  bool brake_momentum_cap = true;
  bool button = true;
  /// Button on the floor: a disc (centre x, z; radius) whose cap stands travel_m above the floor.
  double button_x_m = -0.025, button_z_m = 0.20, button_radius_m = 0.012;
  double button_travel_m = 0.006;
  double button_stiffness_N_per_m = 250.0;
  double button_click_depth_m = 0.004;   ///< force drops here (the click)
  double button_click_drop = 0.6;        ///< fraction of the force lost at the click
  double button_release_depth_m = 0.001; ///< re-arms below this depth
  bool gravity_compensation = true;
  /// Unbalanced weight model (kg, linear in the centre depth z over the workspace; Table X 70–130 g).
  double weight_near_kg = 0.070, weight_far_kg = 0.130;
  double gravity_m_s2 = 9.81;
  /// End-velocity low-pass cutoff. 100 Hz: of 20/30/50/100 Hz, the one whose quantisation dither put the least
  /// energy into the pen at 16 and 24 N/cm (phalanx bench pen-wall --velocity-filter-hz, docs/pen-plant.md).
  double velocity_cutoff_hz = 100.0;
};

struct EndContact {
  bool in_contact = false;
  double penetration_m = 0.0;  ///< deepest wall penetration
  Vec3d force_N{};
  bool brake_applied = false;  ///< a braking pulse was applied this cycle
  Vec3d brake_force_N{};       ///< the braking-pulse part of force_N (after the momentum cap)
};

struct PenRenderOutput {
  std::array<EndContact, 2> end{};  ///< [kBottom] = pencil tip, [kTop] = eraser
  std::array<Vec3d, 2> p_end_m{}, v_end_m_s{};  ///< positions and filtered velocities used
  PenWrench wrench{};               ///< at the pen centre: the end forces + gravity compensation
  Vec3d gravity_force_N{};
  double brake_scale = 1.0;         ///< momentum cap applied to this cycle's braking pulses (1: none)
  bool button_pressed = false;      ///< tip on the button cap
  double button_depth_m = 0.0;
  bool button_clicked = false;      ///< past the click (until released)
  std::uint32_t clicks = 0;
  std::uint32_t marks = 0;          ///< cycles the tip wrote on a wall since the last click
};

class PenScene {
 public:
  /// `model`: the device's kinematic model (its end placement is used by the braking-pulse cap).
  explicit PenScene(const PenSceneConfig& config = {},
                    const phalanx::pen::Model<double>& model = phalanx::pen::defaultModel<double>());
  const PenSceneConfig& config() const { return config_; }
  void setConfig(const PenSceneConfig& config) { config_ = config; }
  /// Forget the velocity filters and contact history (a new session).
  void reset();
  /// One control cycle from the kinematics of this cycle. dt_s: time since the previous call.
  void render(const phalanx::pen::Data<double>& kin, double dt_s, PenRenderOutput& out);
  /// Unbalanced weight (kg) at centre depth z (m).
  double weightKg(double z_m) const;

 private:
  void wall(std::size_t end, double depth, double v_n, const Vec3d& normal, const WallGains& g, std::size_t wall_id,
            PenRenderOutput& out);
  void capBrake(const phalanx::pen::Data<double>& kin, double dt_s, PenRenderOutput& out);
  std::array<std::array<Vec3d, 6>, 2> brake_normal_{};  ///< wall normals of this cycle's pulses (scratch)
  std::array<std::array<double, 6>, 2> brake_vn_{};
  std::array<int, 2> brake_count_{};

  PenSceneConfig config_;
  phalanx::pen::Model<double> model_;
  phalanx::pen::Mat5<double> D_inv_{};  ///< eq 29 in SI, inverted
  bool primed_ = false;
  std::array<Vec3d, 2> last_p_{}, v_filt_{};
  std::array<std::array<bool, 6>, 2> was_in_{};  ///< per end, per wall (x−, x+, floor, z−, z+, button)
  bool clicked_ = false;
  std::uint32_t clicks_ = 0, marks_ = 0;
};

}  // namespace phalanx::host::pen
