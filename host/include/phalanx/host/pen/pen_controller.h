#pragma once
/// The pen's host controller: telemetry (six joint angles) → forward kinematics → PD+B scene rendering per pen
/// end + gravity compensation → pen wrench → force split (Fig. 18, effort-optimal internal force, saturation
/// redistribution) → six joint-torque setpoints, every cycle, without allocation.
#include <array>
#include <string>

#include "phalanx/host/controller.h"
#include "phalanx/host/pen/force_split.h"
#include "phalanx/host/pen/pen_scene.h"
#include "phalanx/pen/kinematics.h"

namespace phalanx::host::pen {

struct PenControllerConfig {
  /// Geometry of the device (default pen::defaultGeometry, the firmware's compile-time geometry).
  phalanx::pen::Geometry<double> geometry = phalanx::pen::defaultGeometry<double>();
  /// Where `geometry` came from (a geometry file; empty = compile-time default). With a file, the firmware's
  /// geometry fingerprint must match (requiredParams).
  std::string geometry_file;
  PenSceneConfig scene{};
  SplitConfig split{};
  bool transparent = false;  ///< true: zero torque on every joint (mode transparent)
};

struct PenControllerStats {
  long cycles = 0;
  long kinematics_unusable = 0;
  long split_redistributed = 0;
  long split_scaled = 0;
  double peak_tip_force_N = 0.0;
  double peak_tip_penetration_m = 0.0;
  double peak_torque_Nm = 0.0;
  std::uint32_t clicks = 0;
  std::uint8_t limit_active_mask_seen = 0;
  /// The tip's wall contact after the first second (the stability judgement of tools/lock-bench.py): cycles in
  /// contact, contacts broken, penetration range and the tip's speed while in contact.
  long settled_cycles = 0;
  long settled_contact_cycles = 0;
  long settled_contact_breaks = 0;
  double settled_penetration_min_m = 1e9, settled_penetration_max_m = 0.0;
  double settled_tip_speed_sq_sum = 0.0;
  double settled_max_separation_m = 0.0;  ///< the tip's largest height above the floor it had touched (a bounce)
  bool floor_touched = false;
  bool last_tip_contact = false;
};

class PenController : public Controller {
 public:
  /// Throws std::invalid_argument if config.geometry is not a pen (pen::makeModel fails); loadPenGeometryYaml
  /// has already refused such files by name.
  explicit PenController(const PenControllerConfig& config = {});
  const char* name() const override { return config_.transparent ? "pen-transparent" : "pen-render"; }
  void update(const TelemetryFrame& tel, double t_s, double dt_s, protocol::Command& cmd) override;
  void summarize(nlohmann::json& out) const override;
  std::string liveLine(const TelemetryFrame& tel) const override;
  std::string liveLegend() const override;
  std::vector<RequiredParam> requiredParams() const override;

  const phalanx::pen::Model<double>& model() const { return model_; }

  const phalanx::pen::Data<double>& kinematics() const { return kin_; }
  const PenRenderOutput& lastRender() const { return render_; }
  const SplitResult& lastSplit() const { return split_result_; }
  const PenControllerStats& stats() const { return stats_; }
  PenScene& scene() { return scene_; }

 private:
  void noteSettledContact(double t_s);
  PenControllerConfig config_;
  phalanx::pen::Model<double> model_;
  PenScene scene_;
  PenForceSplitter splitter_;
  phalanx::pen::Data<double> kin_{};
  PenRenderOutput render_{};
  SplitResult split_result_{};
  bool primed_ = false;
  std::uint64_t last_device_time_us_ = 0;
  PenControllerStats stats_{};
};

}  // namespace phalanx::host::pen
