#include "phalanx/host/benchrun/runner.h"

#include "scoring.h"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "phalanx/fw_sim/glove5_sim.h"
#include "phalanx/fw_sim/pantograph_sim.h"
#include "phalanx/fw_sim/sea_finger_sim.h"
#include "phalanx/host/glove/glove_controller.h"
#include "phalanx/host/lockstep.h"
#include "phalanx/host/metrics.h"
#include "phalanx/host/pen/pen_bench.h"
#include "phalanx/host/pen/pen_controller.h"
#include "phalanx/host/pen/pen_scene.h"
#include "phalanx/host/sea/sea_bench.h"
#include "phalanx/linux/realtime.h"

namespace phalanx::host::benchrun {
namespace {

constexpr double kSmoothHz = 0.5;       // moving average of |G| over frequency (the paper's "filtered", §8.1.3)
constexpr size_t kPenTorque0 = 6;       // pantograph sample: measured motor torque q1 (devices.h)
constexpr long kSafeWaitTicks = 100;   // a safety stop waits at most this long for the device's safe telemetry
constexpr size_t kExcludeAfter = 4;     // rig steps after an unscorable one also not scored (docs/bench-runner.md)

void sleepUntil(uint64_t t_ns) {
  timespec ts{static_cast<time_t>(t_ns / 1000000000ull), static_cast<long>(t_ns % 1000000000ull)};
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

double peakAbs(const std::vector<double>& v) {
  double p = 0.0;
  for (double x : v) p = std::max(p, std::fabs(x));
  return p;
}

/// The simulated device of one step: a lockstep rig plus accessors for the three signals, and for steps that
/// drive the plant themselves (pen-wall: the hand) hooks around each rig step and kind-specific checks.
struct SimTarget {
  std::unique_ptr<fw_sim::SimDevice> device;
  std::unique_ptr<Controller> controller;
  std::unique_ptr<LockstepRig> rig;
  std::function<double()> truth, estimate, setpoint;
  std::function<void(size_t)> before_step;            ///< optional, before rig step k
  std::function<void()> after_step;                   ///< optional, after each rig step
  std::function<void(const Step&, StepResult&)> finish;  ///< optional: step_metrics and checks
  /// optional, after each rig step: true = this step and the next kExcludeAfter are not scored (pen-wall: a
  /// braking pulse, a one-period impulse that the instrument, sampling at poll_hz, cannot resolve).
  std::function<bool()> unscorable;
};

/// Net force two pen-end forces f = J⁻ᵀτ (one per pantograph) put on the pen, minus the gravity compensation:
/// the force the walls get. |·| in N; NaN when a Jacobian is singular.
double penWallForce(const phalanx::pen::Data<double>& kin, const pen::JointVecd& tau, const pen::Vec3d& gravity_comp) {
  namespace pp = phalanx::pen;
  pen::Vec3d f_b{}, f_t{};
  if (!pen::tipForceFromTorques(kin.pantograph[pp::kBottom].J, {tau[0], tau[1], tau[2]}, f_b) ||
      !pen::tipForceFromTorques(kin.pantograph[pp::kTop].J, {tau[3], tau[4], tau[5]}, f_t)) {
    return std::nan("");
  }
  const pen::Vec3d f{f_b[0] + f_t[0] - gravity_comp[0], f_b[1] + f_t[1] - gravity_comp[1], f_b[2] + f_t[2] - gravity_comp[2]};
  return std::sqrt(pp::dot(f, f));
}

/// pen-wall: the wall bench's hand schedule (pen_bench.h) driven step by step, the penetration and energy
/// balance of `phalanx bench pen-wall` accumulated alongside.
struct PenWallState {
  pen::PenSceneConfig scene;
  std::vector<pen::PenWallPhase> phases;
  std::vector<size_t> phase_start;  ///< first rig step of each phase
  sim::PenPlant* plant = nullptr;
  pen::PenController* controller = nullptr;
  phalanx::pen::Data<double> true_kin{};
  double w0 = 0.0, wall_work_J = 0.0, peak_pen_m = 0.0, peak_force_N = 0.0;
  long brake_pulses = 0, split_scaled = 0;
};

void penBeforeStep(PenWallState& s, size_t k) {
  size_t i = 0;
  while (i + 1 < s.phases.size() && k >= s.phase_start[i + 1]) ++i;
  const pen::PenWallPhase& ph = s.phases[i];
  const double t = std::min(static_cast<double>(k - s.phase_start[i]) / kFs, ph.move_s + ph.hold_s);
  const sim::PenVec5 prev = i == 0 ? ph.target : s.phases[i - 1].target;
  sim::PenVec5 tgt{}, tgt_dot{};
  pen::wallBenchHandTarget(ph, prev, t, tgt, tgt_dot);
  s.plant->setHandTarget(tgt, tgt_dot);
  if (ph.release && t >= ph.move_s - 0.15) s.plant->setHandReleased(true);
  // Energy the rendered environment puts into the pen: the motors' work minus what gravity compensation did
  // (as in pen_wall_bench.cpp; the compensation model is the plant's).
  s.w0 = s.plant->truth().motor_work_J + s.plant->truth().gravity_work_J;
}

void penAfterStep(PenWallState& s) {
  const sim::PenTruth& tr = s.plant->truth();
  s.wall_work_J += tr.motor_work_J + tr.gravity_work_J - s.w0;
  s.peak_pen_m = std::max(s.peak_pen_m, pen::wallPenetration(s.scene, tr.B_p_tip));
  const pen::PenRenderOutput& r = s.controller->lastRender();
  if (r.end[phalanx::pen::kBottom].brake_applied) ++s.brake_pulses;
  if (s.controller->lastSplit().status == pen::SplitStatus::kScaled) ++s.split_scaled;
}

/// pen-wall: the wall bench's hand schedule on the pantograph, PD+B walls, and the step's penetration and energy checks.
SimTarget penWallTarget(const Plan& plan, const Step& st) {
  SimTarget t;
  pen::PenWallBenchOptions o;
  o.stiffness_N_per_cm = st.stiffness_N_per_cm;
  o.braking = st.braking;
  auto s = std::make_shared<PenWallState>();
  s->scene = pen::wallBenchScene(o);
  s->phases = pen::wallBenchSchedule(s->scene);
  size_t start = 0;
  for (const pen::PenWallPhase& ph : s->phases) {
    s->phase_start.push_back(start);
    start += static_cast<size_t>(std::lround((ph.move_s + ph.hold_s) * kFs));
  }
  sim::PenPlantConfig pc;
  pc.seed = plan.seed;
  pc.noise = plan.noise;
  pc.scenario = sim::PenHandScenario::kExternal;
  auto dev = std::make_unique<fw_sim::PantographSimDevice>(pc);
  pen::PenControllerConfig cc;
  cc.scene = s->scene;
  auto ctl = std::make_unique<pen::PenController>(cc);
  s->plant = &dev->penPlant();
  s->controller = ctl.get();
  t.controller = std::move(ctl);
  t.device = std::move(dev);
  t.rig = std::make_unique<LockstepRig>(*t.device, *t.controller);
  auto* rig = t.rig.get();
  // Instrument: the force the device TRULY puts on the walls — the plant's motor torques after the amplifier
  // through its true kinematics (f = J⁻ᵀτ per pantograph), minus the force that holds the pen's true weight.
  t.truth = [s] {
    const sim::PenTruth& tr = s->plant->truth();
    if (!phalanx::pen::isUsable(phalanx::pen::computeForward(s->plant->model(), tr.q_rad, s->true_kin))) return std::nan("");
    const pen::Vec3d g{0.0, s->plant->weightKg(tr.x[2]) * s->plant->config().params.gravity_m_s2, 0.0};
    return penWallForce(s->true_kin, tr.motor_torque_Nm, g);
  };
  // Estimate: what the device reports it renders — its measured motor torques (telemetry 6..11) through the
  // kinematics of its encoder angles (Jᵀτ inverted per pantograph), minus the controller's gravity compensation.
  t.estimate = [s, rig] {
    const auto& tel = rig->session().latest();
    pen::JointVecd tau{};
    for (size_t i = 0; i < tau.size(); ++i) tau[i] = static_cast<double>(tel.value[kPenTorque0 + i]);
    if (!phalanx::pen::isUsable(s->controller->kinematics().status)) return std::nan("");
    return penWallForce(s->controller->kinematics(), tau, s->controller->lastRender().gravity_force_N);
  };
  // Setpoint: the wall force the PD+B scene commanded this cycle (both pen ends, braking pulse included).
  t.setpoint = [s] {
    const pen::PenRenderOutput& r = s->controller->lastRender();
    pen::Vec3d f{};
    for (const auto& e : r.end) {
      for (size_t i = 0; i < 3; ++i) f[i] += e.force_N[i];
    }
    const double m = std::sqrt(phalanx::pen::dot(f, f));
    s->peak_force_N = std::max(s->peak_force_N, m);
    return m;
  };
  t.unscorable = [s] {
    const pen::PenRenderOutput& r = s->controller->lastRender();
    return r.end[0].brake_applied || r.end[1].brake_applied;
  };
  t.before_step = [s](size_t k) { penBeforeStep(*s, k); };
  t.after_step = [s] { penAfterStep(*s); };
  t.finish = [s](const Step& step, StepResult& r) {
    const sim::PenTruth& tr = s->plant->truth();
    const double stored = pen::wallStoredEnergy(s->scene, tr.B_p_tip) + pen::wallStoredEnergy(s->scene, tr.B_p_eraser);
    const double generated_mJ = (s->wall_work_J - stored) * 1e3;
    r.step_metrics = {{"peak_tip_penetration_mm", s->peak_pen_m * 1e3},
                      {"wall_energy_generated_mJ", generated_mJ},
                      {"wall_work_mJ", s->wall_work_J * 1e3},
                      {"peak_commanded_wall_force_N", s->peak_force_N},
                      {"braking_pulses", s->brake_pulses},
                      {"split_scaled_cycles", s->split_scaled},
                      {"stiffness_N_per_cm", step.stiffness_N_per_cm},
                      {"braking", step.braking}};
    if (step.penetration_mm_max) {
      r.checks.push_back({"penetration_mm", s->peak_pen_m * 1e3, *step.penetration_mm_max, false,
                          s->peak_pen_m * 1e3 <= *step.penetration_mm_max});
    }
    if (step.wall_energy_generated_mJ_max) {
      r.checks.push_back({"wall_energy_generated_mJ", generated_mJ, *step.wall_energy_generated_mJ_max, false,
                          std::isfinite(generated_mJ) && generated_mJ <= *step.wall_energy_generated_mJ_max});
    }
  };
  return t;
}

SimTarget makeTarget(const Plan& plan, const Step& st) {
  if (st.kind == "pen-wall") return penWallTarget(plan, st);
  SimTarget t;
  if (isGloveStep(st)) {
    // As `phalanx bench glove-free-motion` / `glove-grasp`: the hand closes and opens in transparent mode, or
    // reaches for and squeezes the rigid ball the scene renders.
    const bool grasp = st.kind == "glove-grasp";
    sim::GlovePlantConfig pc;
    pc.seed = plan.seed;
    pc.noise = plan.noise;
    pc.scenario = grasp ? sim::HandScenario::kGrasp : sim::HandScenario::kCloseOpen;
    auto dev = std::make_unique<fw_sim::Glove5SimDevice>(pc);
    t.controller = std::make_unique<glove::GloveController>(gloveStepControllerConfig(st));
    auto* d = dev.get();
    const int f = st.finger;
    t.truth = [d, f] { return d->glovePlant().padForce_N(f); };
    t.device = std::move(dev);
  } else {
    sim::SeaPlantConfig pc;
    pc.seed = plan.seed;
    pc.noise = plan.noise;
    pc.variant = sim::SeaVariant::kRig;
    auto dev = std::make_unique<fw_sim::SeaFingerSimDevice>(pc);
    t.controller = seaStepController(plan, st);
    auto* d = dev.get();
    t.truth = [d] { return d->seaPlant().truth(0).joint_torque_Nm; };  // the load cell's true torque
    t.device = std::move(dev);
  }
  t.rig = std::make_unique<LockstepRig>(*t.device, *t.controller);
  auto* rig = t.rig.get();
  const size_t est_index = isGloveStep(st) ? kGloveForce0 + static_cast<size_t>(st.finger) : kSeaTorque0;
  const size_t sp_index = isGloveStep(st) ? static_cast<size_t>(st.finger) : 0;
  t.estimate = [rig, est_index] { return static_cast<double>(rig->session().latest().value[est_index]); };
  t.setpoint = [rig, sp_index] { return static_cast<double>(rig->lastCommand().setpoint[sp_index]); };
  return t;
}

/// The stop path: the rig commands the safe state from its next step on (LockstepRig::setStopped, makeSafe as in
/// the daemon) and runs until the device's telemetry reports mode safe with outputs off (at most kSafeWaitTicks).
void safeStop(LockstepRig& rig, StepResult& r) {
  r.active_at_stop = (rig.session().latest().state_flags & protocol::state::kOutputsActive) != 0;
  rig.setStopped(true);
  for (long i = 1; i <= kSafeWaitTicks; ++i) {
    rig.step();
    const TelemetryFrame& tel = rig.session().latest();
    if (tel.mode == protocol::Mode::kSafe && (tel.state_flags & protocol::state::kOutputsActive) == 0) {
      r.ticks_to_safe = i;
      return;
    }
  }
}

/// One lockstep step as it runs: the rig stepped in real time, the simulated amplifier fed the plant's truth (and
/// the plan's instrument faults), the instrument polled by its own thread, and the safety watch; every tick's
/// setpoint and estimate kept for the scoring.
class LockstepStepRun {
 public:
  LockstepStepRun(const Plan& plan, const Step& st, SimTarget& target, modbus::SimInstrumentServer& amp,
                  modbus::InstrumentClient& inst, StepResult& r)
      : plan_(plan), st_(st), target_(target), amp_(amp), inst_(inst), r_(r), safety_(plan),
        steps_(static_cast<size_t>(std::lround(st.seconds * kFs))),
        // A sample is "young" for two poll periods of rig time (see series()).
        max_age_steps_(static_cast<size_t>(std::max(2.0, std::ceil(2.0 * kFs / plan.instrument.poll_hz)))),
        sp_(steps_), est_(steps_), set_ns_(steps_), stale_(steps_), excluded_(steps_) {
    samples_.reserve(steps_);
  }
  size_t steps() const { return steps_; }

  /// Rig step k, in real time (its wall-clock slot), and the instrument's reading after it. false: the safety
  /// watch stopped the step (the device was put in its safe state).
  bool tick(size_t k) {
    stepRig(k);
    sleepUntil(t0_ + paused_ns_ + static_cast<uint64_t>(k + 1) * 1000000ull);
    return watch(k, awaitInstrument(k));
  }

  /// The instrument aligned to the rig steps: each sample held from the step whose ground truth it carried (the
  /// last step published before the response arrived; the rig may have run in bursts on a loaded machine, and sim
  /// time is what counts), scored only while young in sim time too (two poll periods): when the machine starved
  /// the rig and it caught up in a burst, the steps of the burst were never measured.
  StepSeries series() {
    std::vector<double> inst_zoh(steps_, std::nan(""));
    size_t si = 0, held_at = 0;
    double held = std::nan("");
    for (size_t k = 0; k < steps_; ++k) {
      while (si < samples_.size() && (k + 1 >= steps_ || samples_[si].first < set_ns_[k + 1])) {
        held = samples_[si].second;
        held_at = k;
        ++si;
      }
      inst_zoh[k] = held;
      if (k - held_at > max_age_steps_) stale_[k] = 1;
    }
    const auto settle = static_cast<size_t>(std::lround(st_.settle_s * kFs));
    return {std::move(sp_), std::move(est_), std::move(inst_zoh), std::move(stale_), std::move(excluded_), settle};
  }

 private:
  /// The rig's step k and what it measured; the amplifier gets the plant's truth (or the plan's lying or hung
  /// instrument from its set time on).
  void stepRig(size_t k) {
    if (target_.before_step) target_.before_step(k);
    target_.rig->step();
    if (target_.after_step) target_.after_step();
    if (target_.unscorable && target_.unscorable()) {
      for (size_t j = k; j < std::min(steps_, k + 1 + kExcludeAfter); ++j) excluded_[j] = 1;
    }
    r_.faults |= target_.rig->session().latest().fault_bits;
    sp_[k] = target_.setpoint();
    est_[k] = target_.estimate();
    const double truth = target_.truth();
    const double t_s = static_cast<double>(k) / kFs;
    if (!lying_ && st_.instrument_lie_at_s >= 0.0 && t_s >= st_.instrument_lie_at_s) lying_ = true;
    amp_.set(lying_ ? truth * st_.instrument_lie_gain + st_.instrument_lie_offset : truth);
    set_ns_[k] = linux_hal::monotonicNs();
    if (!hung_ && st_.instrument_hang_at_s >= 0.0 && t_s >= st_.instrument_hang_at_s) {
      amp_.setResponsive(false);
      hung_ = true;
    }
  }

  /// The instrument's newest reading. Simulation only: the rig's clock is virtual, so when the machine starved the
  /// polling thread the rig waits for the instrument instead of running ahead unmeasured (bounded by the request
  /// timeout; after a timeout it stops waiting until the instrument answers again, and those samples count as stale).
  modbus::InstrumentReading awaitInstrument(size_t k) {
    modbus::InstrumentReading rd = inst_.latest(linux_hal::monotonicNs());
    if (rd.sample_ns == last_sample_ns_ && k > last_sample_step_ + max_age_steps_ && instrument_answering_) {
      const uint64_t w0 = linux_hal::monotonicNs();
      const uint64_t w_end = w0 + static_cast<uint64_t>(plan_.instrument.timeout_ms) * 2000000ull;
      while (rd.sample_ns == last_sample_ns_ && linux_hal::monotonicNs() < w_end) {
        sleepUntil(linux_hal::monotonicNs() + 200000ull);
        rd = inst_.latest(linux_hal::monotonicNs());
      }
      paused_ns_ += linux_hal::monotonicNs() - w0;
      instrument_answering_ = rd.sample_ns != last_sample_ns_;
    }
    return rd;
  }

  /// Keeps a fresh sample and runs the safety watch on it; false after a safety stop.
  bool watch(size_t k, const modbus::InstrumentReading& rd) {
    stale_[k] = rd.stale ? 1 : 0;
    if (rd.valid && rd.sample_ns != last_sample_ns_) {
      samples_.emplace_back(rd.sample_ns, rd.value);
      last_sample_ns_ = rd.sample_ns;
      last_sample_step_ = k;
      instrument_answering_ = true;
      // Against the device's estimate at the rig step whose truth the sample carried (as the scoring does).
      size_t j = k;
      while (j > 0 && set_ns_[j] > rd.sample_ns) --j;
      safety_.sample(k, rd.value, est_[j], r_);
    }
    const std::string cause = safety_.check(k, k - last_sample_step_, rd.last_error, est_[k], r_);
    if (cause.empty()) return true;
    r_.safety_stop = cause;
    r_.stop_tick = static_cast<long>(k);
    safeStop(*target_.rig, r_);
    return false;
  }

  const Plan& plan_;
  const Step& st_;
  SimTarget& target_;
  modbus::SimInstrumentServer& amp_;
  modbus::InstrumentClient& inst_;
  StepResult& r_;
  SafetyWatch safety_;
  const size_t steps_, max_age_steps_;
  std::vector<double> sp_, est_;
  std::vector<uint64_t> set_ns_;
  std::vector<uint8_t> stale_, excluded_;
  std::vector<std::pair<uint64_t, double>> samples_;  ///< instrument samples: (arrival time, value)
  const uint64_t t0_ = linux_hal::monotonicNs();
  uint64_t last_sample_ns_ = 0, paused_ns_ = 0;
  size_t last_sample_step_ = 0;
  bool instrument_answering_ = true, hung_ = false, lying_ = false;
};

StepResult runStep(const Plan& plan, const Step& st, modbus::SimInstrumentServer& amp, modbus::InstrumentClient& inst,
                   size_t index, const Progress& progress) {
  StepResult r;
  r.name = st.name;
  r.kind = st.kind;
  r.unit = plan.instrument.unit;
  SimTarget target = makeTarget(plan, st);
  if (std::string err = target.rig->handshake(); !err.empty()) {
    r.error = "device: " + err;
    return r;
  }
  amp.setResponsive(true);
  amp.set(target.truth());
  // The instrument must be live before the step starts (bounded wait).
  const uint64_t wait_end = linux_hal::monotonicNs() + 1000000000ull;
  while (inst.latest(linux_hal::monotonicNs()).stale && linux_hal::monotonicNs() < wait_end) sleepUntil(linux_hal::monotonicNs() + 2000000ull);
  if (const auto rd = inst.latest(linux_hal::monotonicNs()); rd.stale) {
    r.error = std::string("instrument: no fresh reading before the step (") + rd.last_error + ")";
    return r;
  }

  LockstepStepRun run(plan, st, target, amp, inst, r);
  for (size_t k = 0; k < run.steps() && run.tick(k); ++k) {
    if (k % 100 == 0) progress(index, plan.steps.size(), st.name, static_cast<double>(k) / static_cast<double>(run.steps()));
  }
  progress(index, plan.steps.size(), st.name, 1.0);
  amp.setResponsive(true);
  r.instrument_stats = inst.statsJson(linux_hal::monotonicNs());
  if (!r.safety_stop.empty()) {
    r.error = r.safety_stop;
    if (r.ticks_to_safe < 0) r.error += "; the device did not report its safe state";
    return r;  // nothing scored: the step was cut short
  }
  StepSeries series = run.series();
  const modbus::InstrumentReading last = inst.latest(linux_hal::monotonicNs());
  if (!scoreSeries(plan, st, series, last.last_error, r)) return r;
  if (target.finish) target.finish(st, r);
  if (r.faults != 0 && r.error.empty()) r.error = "device latched faults during the step (bits " + std::to_string(r.faults) + ")";
  r.pass = r.error.empty() && std::all_of(r.checks.begin(), r.checks.end(), [](const Check& c) { return c.pass; });
  return r;
}

}  // namespace

bool scoreSeries(const Plan& plan, const Step& st, StepSeries& s, const char* last_error, StepResult& r) {
  for (size_t k = s.settle; k < s.sp.size(); ++k) {
    if (s.excluded[k]) {
      ++r.samples_excluded;
      continue;
    }
    ++r.samples_total;
    if (s.stale[k] || !std::isfinite(s.inst[k])) {
      ++r.samples_stale;
      continue;
    }
    r.t.push_back(static_cast<double>(k) / kFs);
    r.setpoint.push_back(s.sp[k]);
    r.estimate.push_back(s.est[k]);
    r.instrument.push_back(s.inst[k]);
  }
  const double stale_pct = r.samples_total > 0 ? 100.0 * static_cast<double>(r.samples_stale) / static_cast<double>(r.samples_total) : 100.0;
  if (stale_pct > plan.max_stale_percent) {
    char buf[200];
    std::snprintf(buf, sizeof buf, "instrument: no fresh reading for %.1f %% of the samples (limit %.1f %%); last error: %s",
                  stale_pct, plan.max_stale_percent, last_error);
    r.error = buf;
  }
  if (r.instrument.size() < 100) {
    if (r.error.empty()) r.error = "instrument: too few fresh samples to score";
    return false;
  }
  const bool chirp = st.kind == "sea-rig-chirp";
  // For a chirp the analysis needs an unbroken 1 kHz record: stale samples (if any, within the allowance) are
  // held at the last fresh value.
  std::vector<double> y_inst = r.instrument, y_est = r.estimate, y_sp = r.setpoint;
  if (chirp) {
    y_inst.assign(s.inst.begin() + static_cast<long>(s.settle), s.inst.end());
    y_est.assign(s.est.begin() + static_cast<long>(s.settle), s.est.end());
    y_sp.assign(s.sp.begin() + static_cast<long>(s.settle), s.sp.end());
    double last = 0.0;
    for (double& v : y_inst) {
      if (std::isfinite(v)) last = v;
      else v = last;
    }
  }
  const double f_lo = st.f0_hz + 0.2, f_hi = st.fmax_hz - 0.5;  // the sweep's edges are ramps in the spectrum
  r.est = comparePair(y_est, y_inst, kFs, chirp, f_lo, f_hi);
  r.sp = comparePair(y_inst, y_sp, kFs, chirp, f_lo, f_hi);
  if (!isSeaStep(st)) {
    // Fidelity (eq 15) measures how a torque trajectory is tracked; against the glove's held or zero force and the
    // pen's walls it is a ratio of noise variances: not reported.
    r.est.fidelity_percent = r.sp.fidelity_percent = std::nan("");
  }
  judge(st.estimate_vs_instrument, r.est, "estimate_vs_instrument", r.checks);
  judge(st.setpoint_vs_instrument, r.sp, "setpoint_vs_instrument", r.checks);
  return true;
}

namespace {

nlohmann::json pairJson(const PairMetrics& m) {
  nlohmann::json j = {{"rmse", m.rmse}, {"nrmse_percent", m.nrmse_percent}};
  if (std::isfinite(m.fidelity_percent)) j["fidelity_percent"] = m.fidelity_percent;
  if (m.bandwidth_hz >= 0) {
    j["bandwidth_hz"] = m.bandwidth_hz;
    j["bandwidth_beyond_band"] = m.bandwidth_beyond_band;
  }
  return j;
}

}  // namespace

PairMetrics comparePair(const std::vector<double>& y, const std::vector<double>& r, double fs, bool chirp, double f_lo,
                        double f_hi) {
  PairMetrics m;
  m.rmse = rmse(y, r);
  const double peak = peakAbs(r);
  m.nrmse_percent = peak > 0.0 ? 100.0 * m.rmse / peak : std::nan("");  // the paper's "percent error" (Table 1)
  m.fidelity_percent = sea::fidelityPercent(y, r);                       // eq 15, y measured, y_d reference
  if (!chirp) return m;
  // eq 17: |G(jω)| = |Y(jω)| / |R(jω)| on every DFT bin of the swept band, moving-averaged over kSmoothHz.
  const double df = fs / static_cast<double>(y.size());
  std::vector<double> f, g;
  for (double fr = std::max(df, f_lo - kSmoothHz); fr <= f_hi + kSmoothHz + 1e-9; fr += df) {
    const double ref = sea::amplitudeAt(r, fs, fr);
    f.push_back(fr);
    g.push_back(ref > 0.0 ? sea::amplitudeAt(y, fs, fr) / ref : 0.0);
  }
  const auto half = static_cast<long>(std::lround(0.5 * kSmoothHz / df));
  const double limit = std::pow(10.0, -3.0 / 20.0);
  for (size_t i = 0; i < f.size(); ++i) {
    if (f[i] < f_lo || f[i] > f_hi) continue;
    double s = 0.0;
    long n = 0;
    for (long j = static_cast<long>(i) - half; j <= static_cast<long>(i) + half; ++j) {
      if (j < 0 || j >= static_cast<long>(g.size())) continue;
      s += g[static_cast<size_t>(j)];
      ++n;
    }
    const double gs = s / static_cast<double>(n);
    m.freq_hz.push_back(f[i]);
    m.magnitude_db.push_back(20.0 * std::log10(std::max(gs, 1e-12)));
    if (m.bandwidth_hz < 0.0 && gs < limit) m.bandwidth_hz = f[i];
  }
  if (m.bandwidth_hz < 0.0) {
    m.bandwidth_hz = f_hi;  // never dropped below −3 dB inside the band: at least f_hi
    m.bandwidth_beyond_band = true;
  }
  return m;
}

PlanResult runPlan(const Plan& plan, const Progress& progress) {
  PlanResult out;
  const uint64_t start = linux_hal::monotonicNs();
  // The simulated amplifier serves the plan's register map; the client reads it through the real Modbus path.
  modbus::SimInstrumentServer amp(plan.instrument);
  modbus::InstrumentConfig cfg = plan.instrument;
  std::string err;
  if (cfg.transport == "tcp") {
    err = amp.startTcp(0);
    cfg.host = "127.0.0.1";
    cfg.port = amp.port();
  } else {
    err = amp.startRtu(cfg.serial_device);
  }
  modbus::InstrumentClient inst(cfg);
  if (err.empty()) err = inst.start();
  std::string stopped_by;  // a safety stop ends the plan: the remaining steps do not run
  for (size_t i = 0; i < plan.steps.size(); ++i) {
    StepResult r;
    if (!stopped_by.empty()) {
      r.name = plan.steps[i].name;
      r.kind = plan.steps[i].kind;
      r.skipped = true;
      r.error = "not run: " + stopped_by;
    } else if (!err.empty()) {
      r.name = plan.steps[i].name;
      r.kind = plan.steps[i].kind;
      r.error = err;
    } else {
      r = runStep(plan, plan.steps[i], amp, inst, i, progress);
      if (!r.safety_stop.empty()) stopped_by = "safety stop in step " + std::to_string(i + 1) + " (" + r.name + ")";
    }
    out.steps.push_back(std::move(r));
  }
  inst.stop();
  amp.stop();
  out.pass = std::all_of(out.steps.begin(), out.steps.end(), [](const StepResult& s) { return s.pass; });
  out.wall_s = static_cast<double>(linux_hal::monotonicNs() - start) * 1e-9;
  return out;
}

nlohmann::json toJson(const PlanResult& r) {
  nlohmann::json j;
  j["pass"] = r.pass;
  j["wall_s"] = r.wall_s;
  for (const StepResult& s : r.steps) {
    nlohmann::json sj = {{"name", s.name}, {"kind", s.kind}, {"pass", s.pass}, {"samples", s.samples_total},
                         {"samples_stale", s.samples_stale}, {"faults", s.faults}};
    if (s.samples_excluded > 0) sj["samples_excluded"] = s.samples_excluded;
    if (!s.error.empty()) sj["error"] = s.error;
    if (!s.safety_stop.empty()) {
      sj["safety_stop"] = s.safety_stop;
      sj["stop_tick"] = s.stop_tick;
      sj["ticks_to_safe"] = s.ticks_to_safe;
      sj["active_at_stop"] = s.active_at_stop;
    }
    if (s.skipped) sj["skipped"] = true;
    if (s.samples_total > 0 || s.stop_tick >= 0) {  // the step ran
      sj["safety"] = {{"longest_silence_ms", s.longest_silence_ticks}, {"longest_disagreement_ms", s.longest_disagreement_ticks},
                       {"largest_disagreement", s.largest_disagreement}};
    }
    if (!s.instrument.empty()) {
      sj["estimate_vs_instrument"] = pairJson(s.est);
      sj["setpoint_vs_instrument"] = pairJson(s.sp);
    }
    for (const Check& c : s.checks) {
      sj["checks"].push_back({{"what", c.what}, {"value", c.value}, {c.is_min ? "min" : "max", c.limit}, {"pass", c.pass}});
      if (!c.note.empty()) sj["checks"].back()["note"] = c.note;
    }
    sj["instrument"] = s.instrument_stats;
    if (!s.step_metrics.is_null()) sj["metrics"] = s.step_metrics;
    if (!s.alignment.is_null()) sj["alignment"] = s.alignment;
    if (!s.link.is_null()) sj["link"] = s.link;
    j["steps"].push_back(sj);
  }
  j["mode"] = r.session.is_null() ? "lockstep" : "realtime";
  if (!r.session.is_null()) j["session"] = r.session;
  return j;
}

}  // namespace phalanx::host::benchrun
