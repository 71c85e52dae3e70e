#pragma once
/// The sea_finger host controller: telemetry (five joint angle sensors, SEA torques) → kinematics estimator →
/// finger-joint torque control (eq 9–11) → exoskeleton joint torque setpoints, every cycle, without allocation.
#include <array>

#include "phalanx/host/controller.h"
#include "phalanx/host/sea/sea_estimator.h"

namespace phalanx::host::sea {

/// sea_finger telemetry channels (kSeaFingerLayout, common/include/phalanx/protocol/devices.h).
inline constexpr size_t kSampleSensor0 = 0;     ///< samples 0..4: joint angle sensors, ps::SensorIndex order
inline constexpr size_t kSampleSeaTorque0 = 7;  ///< samples 7..8: SEA torque (eq 7) at θ1r, θ6r

/// Desired finger joint torque y_d(t) = A sin(2π f t + φ) + μ per joint (eq 18), N·m (positive = extension).
struct FingerTorqueProfile {
  /// Defaults from §8.6: the paper's RMS errors and NRMSEs (0.0041 N·m = 1.7 %, 0.0012 N·m = 3.4 %) imply
  /// peak-to-peak ranges of ≈ 0.24 N·m at MCP and ≈ 0.035 N·m at PIP; 0.5 Hz as in §5.3/§7.1.2.
  std::array<double, 2> amplitude_Nm{0.12, 0.018};
  std::array<double, 2> mean_Nm{0.0, 0.0};
  std::array<double, 2> phase_rad{0.0, 0.0};
  double frequency_hz = 0.5;
};

enum class SeaFingerMode { kTransparent, kFingerTorque };

struct SeaFingerControllerConfig {
  SeaFingerMode mode = SeaFingerMode::kFingerTorque;
  FingerTorqueProfile profile{};
  FingerTorqueLimits limits{};
  Model model = ps::defaultModel<double>();
  /// Ramp-in of the profile amplitude (s), so the first command after the handshake is zero torque.
  double ramp_s = 0.5;
};

/// Session figures for the summary.
struct SeaFingerStats {
  long cycles = 0;
  long invalid_kinematics = 0;   ///< cycles with no valid J_n (zero torque commanded)
  long least_squares = 0;        ///< cycles where a chain used the least-squares fallback
  long saturated = 0;            ///< cycles where τ_j,d was scaled down
  std::array<double, 2> sq_err_finger{};   ///< Σ (ŷ − y_d)² (N·m)², ŷ from eq 9
  std::array<double, 2> min_y_d{1e9, 1e9};
  std::array<double, 2> max_y_d{-1e9, -1e9};
  std::array<double, 2> sq_exo_torque{};   ///< Σ τ̂_j² (transparency residual)
  long scored = 0;
};

class SeaFingerController : public Controller {
 public:
  explicit SeaFingerController(const SeaFingerControllerConfig& config);
  const char* name() const override {
    return config_.mode == SeaFingerMode::kTransparent ? "sea-transparent" : "sea-finger-torque";
  }
  void update(const TelemetryFrame& tel, double t_s, double dt_s, protocol::Command& cmd) override;
  void summarize(nlohmann::json& out) const override;
  std::string liveLine(const TelemetryFrame& tel) const override;
  std::string liveLegend() const override;

  /// Desired finger torque and its rate at session time t_s (eq 18, with the ramp-in).
  void desired(double t_s, Vec2& y_d_Nm, Vec2& y_d_rate_Nm_s) const;
  const SeaEstimator& estimator() const { return estimator_; }
  const FingerTorqueMap& lastMap() const { return map_; }
  const SeaFingerStats& stats() const { return stats_; }

 private:
  SeaFingerControllerConfig config_;
  SeaEstimator estimator_;
  FingerTorqueMap map_{};
  SeaFingerStats stats_{};
  Vec2 last_y_d_{};
  uint64_t last_device_time_us_ = 0;
  bool primed_ = false;
};

}  // namespace phalanx::host::sea
