#pragma once
/// SEA bench scenarios (`phalanx bench sea-rig-sine|sea-rig-chirp`), run in lockstep on the simulated §7.1 test
/// rig (seeds/001): the sea_finger firmware app, the SEA plant with its sensor noise, the link codec and a host
/// controller that streams the desired joint torque. Each scenario runs the paper's plain PID baseline and/or our
/// controller (the firmware's kController switch) on the same plant and seed.
///
/// Every metric is computed from what the host sees in telemetry (the load cell is wired to the board's ADC on
/// the rig, sample 11), so the same code can score a real rig; the plant's ground truth is reported beside it.
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/controller.h"

namespace phalanx::host::sea {

struct SeaBenchOptions {
  double seconds = 0.0;             ///< 0: the scenario's default length
  uint32_t seed = 1;
  bool noise = true;
  std::string controller = "both";  ///< both | paper | ours
  double peak_Nm = 0.3;             ///< sine: peak torque (§7.1.2: 0.15 or 0.3)
  double hz = 0.5;                  ///< sine: frequency (§7.1.2: 0.5 Hz)
  double chirp_amplitude_Nm = 0.15; ///< chirp: τ_A (eq 16)
  double chirp_f0_hz = 0.1;         ///< chirp: start frequency
  double chirp_fmax_hz = 25.0;      ///< chirp: frequency reached at the end
  double plant_backlash_scale = 1.0;  ///< scales the plant's cable play b_0, b_1 (model-mismatch studies)
  bool finger_user_holds = false;     ///< finger torque: the user holds the rest posture instead of relaxing
};

/// Streams τ_d(t) to SEA `sea` in setpoint mode (the other SEA gets 0) and selects the firmware controller at
/// start-up (device parameter kController). kind: 0 sine (eq 18 with zero phase and mean), 1 chirp (eq 16).
class SeaTrajectoryController : public Controller {
 public:
  enum class Shape { kSine, kChirp };
  SeaTrajectoryController(Shape shape, double amplitude_Nm, double f0_hz, double f1_hz, bool paper, int sea = 0);
  const char* name() const override { return paper_ ? "sea-paper-pid" : "sea-ours"; }
  void update(const TelemetryFrame& tel, double t_s, double dt_s, protocol::Command& cmd) override;
  std::vector<std::pair<uint16_t, float>> startupParams() const override;
  double startupSettleS() const override { return 0.2; }
  /// Desired torque at time t (s since the trajectory started).
  double desired(double t_s) const;
  /// Time (rig clock) at which the trajectory started (the first update).
  double startS() const { return start_s_; }

 private:
  Shape shape_;
  double amplitude_, f0_, f1_;
  bool paper_;
  int sea_;
  double start_s_ = -1.0;
};

/// Fidelity F (eq 15), percent: (1 − var(y − y_d) / var(y)) · 100, y measured, y_d desired.
double fidelityPercent(const std::vector<double>& measured, const std::vector<double>& desired);

/// Single-sided amplitude of the DFT of x (sampled at fs) at frequency f (direct evaluation of one bin).
double amplitudeAt(const std::vector<double>& x, double fs_hz, double f_hz);

/// Sinusoid tracking on the rig (§7.1.1–7.1.2): RMSE, NRMSE (RMSE / peak, the paper's "percent error"),
/// fidelity (eq 15) of the load-cell torque, the same for the SEA estimate, per controller.
nlohmann::json benchRigSine(const SeaBenchOptions& options);

/// Finger-joint torque tracking on the simulated finger (§7.6, §8.6): the host's SeaFingerController (eq 9–11)
/// maps sinusoidal finger MCP/PIP torques (eq 18) to exoskeleton torque setpoints; the relaxed finger (eq 13–14)
/// moves under them. NRMSE = RMSE / peak-to-peak of y_d (the paper's 1.7 % = 0.0041 N·m of 0.24 N·m), of the
/// host's eq 9 estimate from telemetry and of the true applied finger torque, per firmware controller.
nlohmann::json benchFingerTorque(const SeaBenchOptions& options);

/// Dynamic transparency (§7.7, §8.7): the simulated user moves the finger randomly while the device renders zero
/// exoskeleton torque; residual exoskeleton joint torque RMSE (telemetry estimate and truth), per controller.
nlohmann::json benchTransparency(const SeaBenchOptions& options);

/// Linear chirp on the rig (§7.1.3, eq 16–17): closed-loop magnitude |G_CL| = |τ_measured(jω)| / |τ_r(jω)|
/// from single-sided amplitude spectra, moving-averaged over frequency, and the −3 dB bandwidth, per controller.
nlohmann::json benchRigChirp(const SeaBenchOptions& options);

}  // namespace phalanx::host::sea
