#pragma once
/// The hardware-in-the-loop bench runner (`phalanx bench run PLAN.yaml`, docs/bench-runner.md): executes a plan of
/// steps against a device while a reference instrument (a Modbus load-cell / torque-transducer amplifier) measures
/// what the device really does, records device estimate, instrument reading and setpoint, scores them with the
/// SEA paper's metrics (seeds/001: RMSE, NRMSE, fidelity eq 15, −3 dB bandwidth eq 16–17) and judges each step
/// against the plan's limits.
///
/// Devices: sim:sea_rig (the §7.1 SEA test rig: sea_finger firmware + rig plant, joint clamped to the load cell),
/// sim:glove5 (fingertip force sensor on one finger) and sim:pantograph (the haptic pen pressed into its virtual
/// stiff box, seeds/004 §VI: the force the walls should render, the device's Jᵀτ estimate, the true force). In simulation the instrument is a simulated Modbus
/// amplifier served from the plant's ground truth and read back through the real Modbus client, in real time.
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/modbus/instrument.h"

namespace phalanx::host::benchrun {

/// Limits on one comparison (absent: not judged).
struct PairLimits {
  std::optional<double> rmse_max;             ///< SI units of the signal
  std::optional<double> nrmse_percent_max;    ///< RMSE / peak |reference| · 100
  std::optional<double> fidelity_percent_min; ///< eq 15
  std::optional<double> bandwidth_hz_min;     ///< eq 17, −3 dB (chirp steps)
};

struct Step {
  std::string name;
  std::string kind;              ///< sea-rig-sine | sea-rig-chirp | glove-free-motion | glove-grasp | pen-wall
  double seconds = 8.0;
  double settle_s = 1.0;         ///< excluded from the metrics (start transient)
  double peak_Nm = 0.3;          ///< sine
  double hz = 0.5;               ///< sine
  double amplitude_Nm = 0.15;    ///< chirp τ_A (eq 16)
  double f0_hz = 0.1;            ///< chirp
  double fmax_hz = 10.0;         ///< chirp: instantaneous frequency at the end
  int finger = 1;                ///< glove: 0 thumb … 4 little
  double stiffness_N_per_cm = 3.0;  ///< pen-wall: horizontal walls (floor 0.7×), the paper's stiff box (004 §VI)
  bool braking = true;           ///< pen-wall: braking pulse at contact onset
  std::optional<double> penetration_mm_max;        ///< pen-wall: deepest true tip/eraser penetration
  std::optional<double> wall_energy_generated_mJ_max;  ///< pen-wall: passivity, energy the walls generated
  double instrument_hang_at_s = -1.0;  ///< simulation fault: the amplifier stops answering at this time
  /// Simulation fault: from this time on the amplifier serves truth · instrument_lie_gain + instrument_lie_offset
  /// (a broken load cell: gain 0; a shifted one: an offset). −1: never.
  double instrument_lie_at_s = -1.0;
  double instrument_lie_gain = 1.0;
  double instrument_lie_offset = 0.0;
  PairLimits estimate_vs_instrument;
  PairLimits setpoint_vs_instrument;
};

/// The plan's safety limits (top-level `safety:`, required; docs/bench-runner.md "Safety"). The loader refuses a
/// plan whose effort_max exceeds the device's own limit (protocol::DeviceLayout::setpoint_limit, the limits stage's)
/// or whose steps command beyond effort_max; at run time a silent or disagreeing instrument stops the step and the
/// plan, the device commanded safe.
struct Safety {
  double effort_max = 0.0;          ///< largest |setpoint| a step may command, device setpoint unit (N·m, N)
  double instrument_silence_ms = 0; ///< no fresh instrument sample for longer than this (rig ticks, 1 ms each): stop
  double disagreement_max = 0.0;    ///< |instrument − device estimate| beyond this (instrument unit) …
  double disagreement_ms = 0.0;     ///< … for longer than this (rig ticks, 1 ms each): stop
};

struct Plan {
  std::string source;                 ///< file name, for messages
  /// Any device string the daemon accepts (sim:sea_rig | sim:glove5 | sim:pantograph, serial:…, can:…, usb:…).
  std::string device = "sim:sea_rig";
  /// What the steps run on: sea_rig | glove5 | pantograph (sim: devices: their name; else the plan's device_type).
  std::string device_type = "sea_rig";
  /// Real time on a sim: device: firmware-sim serves the plant's truth as the instrument (true, the default), or
  /// the `instrument:` block's address is read (false: an amplifier outside the simulation). Real devices: always
  /// the block's address.
  bool sim_instrument = true;
  /// sim: instrument: firmware-sim serves each tick's value this much later (a slow amplifier; tests the alignment).
  double sim_instrument_delay_ms = 0.0;
  std::string controller = "ours";    ///< sea: ours | paper (001 plain PID)
  uint32_t seed = 1;
  bool noise = true;
  std::string report;                 ///< HTML path ("" → <plan>.html)
  modbus::InstrumentConfig instrument;
  double max_stale_percent = 1.0;     ///< a step fails if more of its samples had no fresh instrument reading
  Safety safety;
  std::vector<Step> steps;
};

/// The device's own |setpoint| limit for a plan's device type ("sea_rig", "glove5", "pantograph"; "sim:" prefix
/// allowed), in its setpoint unit; 0 if unknown.
double deviceEffortLimit(const std::string& device_type);
/// The largest |setpoint| a step commands: sine peak_Nm, chirp amplitude_Nm, glove free motion 0 (transparent),
/// glove grasp the rendered contact force's clamp (10 N), pen-wall the force split's per-joint torque limit (the
/// PD+B scene is closed-loop; the split caps it).
double stepEffortMax(const Step& step);
/// glove-free-motion or glove-grasp: a step on the glove, whose signals are one finger's pad force.
bool isGloveStep(const Step& step);
/// sea-rig-sine or sea-rig-chirp: a torque trajectory on the SEA rig (fidelity, eq 15, is reported for these only).
bool isSeaStep(const Step& step);

/// Parse and validate a plan; "" or "<source>: <key>: <problem>".
std::string loadPlanText(const std::string& yaml, const std::string& source, Plan& plan);
std::string loadPlanFile(const std::string& path, Plan& plan);
/// `--device`: run the plan on another device string of its device_type; "" or "--device: <problem>".
std::string setPlanDevice(Plan& plan, const std::string& device);

/// One comparison's scores. NaN where a metric is undefined (e.g. NRMSE of a zero reference).
struct PairMetrics {
  double rmse = 0, nrmse_percent = 0, fidelity_percent = 0;
  double bandwidth_hz = -1;          ///< chirp only; −1 otherwise
  bool bandwidth_beyond_band = false;
  std::vector<double> freq_hz, magnitude_db;  ///< smoothed |G| over the evaluated band (chirp)
};

struct Check {
  std::string what;  ///< "estimate_vs_instrument.rmse"
  double value, limit;
  bool is_min;       ///< limit is a minimum (else a maximum)
  bool pass;
  /// What the value means beyond its number: "-3 dB not reached within the sweep" (the bandwidth is at least it).
  std::string note = {};
};

struct StepResult {
  std::string name, kind, unit;
  std::string error;                 ///< device/instrument problem; the step fails
  /// Safety stop (instrument silent / disagreeing): "" if none. The step was cut short and the device
  /// commanded safe through the rig's stop path; the plan's remaining steps did not run.
  std::string safety_stop;
  long stop_tick = -1;               ///< rig tick (since the step's start) of the stop decision; −1 none
  /// Rig ticks from the decision until the device's telemetry reported mode safe with outputs off; −1 never.
  long ticks_to_safe = -1;
  bool active_at_stop = false;       ///< the device's telemetry at the decision: outputs driven (it was pushing)
  /// The safety margins the step used (rig ticks, 1 ms each): its longest instrument silence and its longest
  /// run of fresh samples disagreeing with the estimate by more than safety.disagreement_max.
  long longest_silence_ticks = 0, longest_disagreement_ticks = 0;
  double largest_disagreement = 0.0;  ///< largest |instrument − estimate| over the fresh samples (instrument unit)
  bool skipped = false;              ///< not run: an earlier step's safety stop ended the plan
  std::vector<double> t, setpoint, estimate, instrument;  ///< fresh-instrument samples after settle
  uint64_t samples_total = 0, samples_stale = 0;
  uint64_t samples_excluded = 0;     ///< not scored by design (pen-wall: the braking pulses and 4 ms after them)
  uint16_t faults = 0;
  PairMetrics est, sp;               ///< estimate vs instrument, setpoint vs instrument
  std::vector<Check> checks;
  /// Real time (runPlanOnDevice): the instrument's delay against the device's telemetry clock and how the step was
  /// carried (docs/bench-runner.md "Real time"). Empty in lockstep.
  nlohmann::json alignment;
  nlohmann::json link;
  nlohmann::json instrument_stats;
  nlohmann::json step_metrics;       ///< kind-specific figures (pen-wall: penetration, wall energy), SI-suffixed keys
  bool pass = false;
};

struct PlanResult {
  std::vector<StepResult> steps;
  bool pass = false;
  double wall_s = 0;
  /// Real time: what the session runner reported (link, device, round trip, telemetry, commands and the limits
  /// stage's counts, exit code). Null in lockstep.
  nlohmann::json session;
};

/// Progress: (step index, step count, step name, fraction 0..1 of that step).
using Progress = std::function<void(size_t, size_t, const std::string&, double)>;

/// Run every step in order in lockstep (`--lockstep`; sim: devices): firmware, plant and host stepped in one process
/// at 1 kHz paced to wall-clock time, the instrument a simulated amplifier in this process polled in real time.
PlanResult runPlan(const Plan& plan, const Progress& progress);

/// How runPlanOnDevice reaches the device (the rest is the plan's).
struct DeviceRunOptions {
  std::string firmware_sim;          ///< sim: devices: path of firmware-sim ("": next to this executable)
  bool realtime = true;              ///< SCHED_FIFO + locked memory for the session thread, as phalanxd
};

/// What a plan needs that the real-time runner does not do ("" or the key and why): pen-wall steps, the
/// lockstep-only instrument faults and noise: false need --lockstep; glove steps on different fingers.
std::string realtimeUnsupported(const Plan& plan);

/// Run the plan as one session of the daemon's session runner (runSession, docs/session-runner.md) on plan.device:
/// the plan is the session's command source, every command passes the limits stage, the instrument is polled on its
/// own thread, and each step's instrument samples are aligned to the device's telemetry clock by an estimated
/// delay before scoring (alignInstrument).
PlanResult runPlanOnDevice(const Plan& plan, const Progress& progress, const DeviceRunOptions& options);

/// The instrument's delay behind the device, estimated without a shared clock (docs/bench-runner.md "Alignment").
struct Alignment {
  bool ok = false;
  double delay_ms = 0.0;         ///< instrument sample time minus the time (host clock) of the device tick it shows
  /// Spread of the quarter-step estimates whose quarter follows the estimate (at least the search step).
  double uncertainty_ms = 0.0;
  double correlation = 0.0;      ///< normalised cross-correlation at the delay
  std::vector<double> quarter_delay_ms, quarter_correlation;
  size_t quarters_used = 0;      ///< quarters correlating at least as well as the whole step must
  std::string error;             ///< why ok is false
};
/// dev_host_ms: each device tick's time on the host clock (ms, ascending); est: the device's estimate at it;
/// sample_ms / value: the instrument's samples (host arrival time). Maximises the normalised cross-correlation of
/// the instrument against the estimate held at (sample time − delay) over −max_lag_ms/4 … max_lag_ms.
Alignment alignInstrument(const std::vector<double>& dev_host_ms, const std::vector<double>& est,
                          const std::vector<double>& sample_ms, const std::vector<double>& value, double max_lag_ms);

/// Metrics of y (the instrument) against a reference r, sampled at fs_hz. chirp: also eq 17 between f_lo and f_hi.
PairMetrics comparePair(const std::vector<double>& y, const std::vector<double>& r, double fs_hz, bool chirp,
                        double f_lo, double f_hi);

nlohmann::json toJson(const PlanResult& r);

}  // namespace phalanx::host::benchrun

namespace phalanx::host::benchrun {
/// `phalanx bench run`: load the plan, run it with progress on stderr, write the HTML report, print the JSON
/// summary on stdout. Returns the exit code: 0 every step passed, 1 a step failed, 2 the plan is invalid,
/// 3 the report could not be written.
/// device: "" or a device string that replaces the plan's (its type must be the plan's device_type); lockstep: run
/// a sim: plan in lockstep (runPlan) instead of in real time on the device (runPlanOnDevice).
int benchRunMain(const std::string& plan_path, const std::string& report_path, const std::string& device = "",
                 bool lockstep = false, bool realtime = true);
}  // namespace phalanx::host::benchrun
