// A bench plan in real time on any device (docs/bench-runner.md "Real time"): the plan is the command source of one
// session of the daemon's session runner (runSession), so its commands pass the same limits stage as every other
// source; the instrument is polled on its own thread; afterwards each step's instrument samples are aligned to the
// device's telemetry clock by an estimated delay and scored with the lockstep runner's metrics.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <optional>
#include <sstream>
#include <thread>

#include "phalanx/host/benchrun/runner.h"
#include "phalanx/host/command_limits.h"
#include "phalanx/host/controller.h"
#include "phalanx/host/daemon.h"
#include "phalanx/host/glove/glove_controller.h"
#include "phalanx/host/sea/sea_bench.h"
#include "phalanx/host/session.h"
#include "phalanx/linux/realtime.h"
#include "scoring.h"

namespace phalanx::host::benchrun {
namespace {

constexpr long kSafeWaitCycles = 100;  // a safety stop waits at most this long for the device's safe telemetry
constexpr double kMaxLagMs = 60.0;     // the alignment searches −15 … +60 ms
constexpr double kLagStepMs = 0.25;
constexpr size_t kClockWindow = 25;  // frames either side of a frame whose least transport delay maps its tick
// The delay is trusted when the instrument follows the estimate (correlation) and the four quarters of the step
// agree on it; else the step's excitation does not fix a delay and nothing is scored.
constexpr double kMinCorrelation = 0.5;
constexpr double kMaxUncertaintyMs = 2.0;
const char* const kFingers[] = {"thumb", "index", "middle", "ring", "little"};

/// One session cycle as the bench saw it (the newest telemetry and the command computed from it).
struct CycleRow {
  uint64_t rx_ns = 0, dev_us = 0;
  uint16_t seq = 0, faults = 0;
  double est = 0.0, sp = 0.0;
};

struct SampleRow {
  uint64_t ns = 0;
  double value = 0.0;
};

/// The plan's state shared by its controller and the hooks (both on the session thread).
struct PlanState {
  size_t step = 0;    ///< the step running (== steps: done)
  bool safe = false;  ///< a safety stop: the safe command from now on
};

/// The plan as the session's controller: step i's own controller while it runs, the safe command (makeSafe, the
/// daemon's) after a safety stop or the last step.
class PlanController : public Controller {
 public:
  PlanController(std::vector<std::unique_ptr<Controller>> steps, const PlanState& state)
      : steps_(std::move(steps)), state_(state) {}
  const char* name() const override { return "bench-plan"; }
  void update(const TelemetryFrame& tel, double t_s, double dt_s, protocol::Command& cmd) override {
    if (state_.safe || state_.step >= steps_.size()) {
      makeSafe(cmd);
      return;
    }
    steps_[state_.step]->update(tel, t_s, dt_s, cmd);
  }
  std::vector<std::pair<uint16_t, float>> startupParams() const override { return steps_.front()->startupParams(); }
  double startupSettleS() const override { return steps_.front()->startupSettleS(); }
  bool usesGainScale() const override { return steps_.front()->usesGainScale(); }

 private:
  std::vector<std::unique_ptr<Controller>> steps_;
  const PlanState& state_;
};

std::unique_ptr<Controller> stepController(const Plan& plan, const Step& st) {
  if (isGloveStep(st)) return std::make_unique<glove::GloveController>(gloveStepControllerConfig(st));
  return seaStepController(plan, st);
}

/// firmware-sim's "instrument: modbus tcp 127.0.0.1:PORT …" / "… rtu /dev/pts/N …" line into the client's address.
std::string simInstrumentAddress(const std::string& line, modbus::InstrumentConfig& cfg) {
  std::istringstream in(line);
  std::string word, modbus, transport, where;
  in >> word >> modbus >> transport >> where;
  if (transport == "tcp") {
    const auto colon = where.rfind(':');
    if (colon == std::string::npos) return "cannot read the simulated instrument's address from '" + line + "'";
    cfg.transport = "tcp";
    cfg.host = where.substr(0, colon);
    cfg.port = static_cast<unsigned>(std::strtoul(where.c_str() + colon + 1, nullptr, 10));
    return {};
  }
  if (transport == "rtu" && !where.empty()) {
    cfg.transport = "rtu";
    cfg.serial_device = where;
    return {};
  }
  return "cannot read the simulated instrument's address from '" + line + "'";
}

/// The session's observer: steps the plan, records every cycle and instrument sample into memory reserved before
/// the first cycle, and runs the plan's safety watch (docs/bench-runner.md "Safety"; counted in cycles, 1 ms each).
class BenchHooks : public SessionHooks {
 public:
  BenchHooks(const Plan& plan, bool sim_instrument) : plan_(plan), sim_instrument_(sim_instrument), results_(plan.steps.size()) {
    size_t cycles = 0;
    for (const Step& st : plan.steps) {
      slots_.push_back({cycles, static_cast<size_t>(std::lround(st.seconds * kFs))});
      cycles += slots_.back().cycles;
    }
    rows_.reserve(cycles + kSafeWaitCycles + 16);
    at_step_end_.resize(plan.steps.size());
    step_end_.reserve(plan.steps.size());
    samples_.reserve(static_cast<size_t>(static_cast<double>(cycles) / kFs * plan.instrument.poll_hz * 1.5) + 1024);
    const bool glove = plan.device_type == "glove5";
    const size_t finger = glove ? static_cast<size_t>(plan.steps.front().finger) : 0;
    est_index_ = glove ? kGloveForce0 + finger : kSeaTorque0;
    sp_index_ = finger;
  }

  std::unique_ptr<Controller> makeController(const protocol::DeviceLayout& layout, std::string& error) override {
    const protocol::DeviceType want =
        plan_.device_type == "glove5" ? protocol::DeviceType::kGlove5 : protocol::DeviceType::kSeaFinger;
    if (layout.type != want) {
      error = std::string("bench: the plan's steps run on ") + plan_.device_type + ", but " + plan_.device + " is a " + layout.name;
      return nullptr;
    }
    std::vector<std::unique_ptr<Controller>> steps;
    for (const Step& st : plan_.steps) steps.push_back(stepController(plan_, st));
    return std::make_unique<PlanController>(std::move(steps), state_);
  }

  std::string onStart(const protocol::DeviceLayout&, const nlohmann::json& info) override {
    modbus::InstrumentConfig cfg = plan_.instrument;
    if (sim_instrument_) {
      const nlohmann::json& link = info["link"];
      if (!link.is_object() || !link.contains("instrument")) return "bench: the simulated firmware serves no instrument";
      if (std::string err = simInstrumentAddress(link["instrument"].get<std::string>(), cfg); !err.empty()) return "bench: " + err;
    }
    link_ = info.contains("link") ? info["link"] : nlohmann::json();
    instrument_cfg_ = cfg;
    inst_ = std::make_unique<modbus::InstrumentClient>(cfg);
    if (std::string err = inst_->start(); !err.empty()) return "instrument: " + err;
    // The instrument must be live before the first step (bounded wait), as in lockstep.
    const uint64_t end = linux_hal::monotonicNs() + 2000000000ull;
    while (inst_->latest(linux_hal::monotonicNs()).stale && linux_hal::monotonicNs() < end) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    if (const modbus::InstrumentReading rd = inst_->latest(linux_hal::monotonicNs()); rd.stale) {
      return std::string("instrument: no fresh reading before the plan (") + rd.last_error + ")";
    }
    watch_.emplace(plan_);
    started_.store(true);
    return {};
  }

  void onCycle(uint64_t, double, const TelemetryFrame& tel, const protocol::Command& cmd) override {
    if (done_ || rows_.size() == rows_.capacity()) {
      done_ = true;
      return;
    }
    rows_.push_back({tel.host_rx_ns, tel.device_time_us, tel.seq, tel.fault_bits,
                     static_cast<double>(tel.value[est_index_]), static_cast<double>(cmd.setpoint[sp_index_])});
    const size_t k = rows_.size() - 1;
    if (state_.safe) return awaitSafe(tel, k);
    results_[state_.step].faults |= tel.fault_bits;
    watchInstrument(k, tel);
    if (state_.safe) return;
    if (++in_step_ >= slots_[state_.step].cycles) return nextStep();
    if (in_step_ % 100 == 0) {
      progress_frac_.store(static_cast<double>(in_step_) / static_cast<double>(slots_[state_.step].cycles),
                           std::memory_order_relaxed);
    }
  }

  bool stopRequested() override { return done_; }
  void onEnd(const nlohmann::json& summary) override {
    summary_ = summary;
    if (inst_) inst_->stop();
  }

  /// For the progress thread: the step running and its share done (relaxed reads of the session thread's counters).
  size_t progressStep() const { return progress_step_.load(std::memory_order_relaxed); }
  double progressFraction() const { return progress_frac_.load(std::memory_order_relaxed); }

  bool started() const { return started_.load(); }  ///< from any thread
  /// After the session: each step's result, aligned and scored.
  std::vector<StepResult> finish();

 private:
  void watchInstrument(size_t k, const TelemetryFrame& tel) {
    StepResult& r = results_[state_.step];
    const modbus::InstrumentReading rd = inst_->latest(linux_hal::monotonicNs());
    at_step_end_[state_.step] = rd;  // the step's instrument counters and error, as they were when it ran
    if (rd.valid && rd.sample_ns != last_sample_ns_) {
      if (samples_.size() < samples_.capacity()) samples_.push_back({rd.sample_ns, rd.value});
      last_sample_ns_ = rd.sample_ns;
      last_sample_cycle_ = k;
      // Against the estimate of the newest frame that had arrived before the sample (the alignment refines this
      // afterwards; the watch's bounds are tens of ms, far above the delay).
      size_t j = k;
      while (j > 0 && k - j < 64 && rows_[j].rx_ns > rd.sample_ns) --j;
      watch_->sample(in_step_, rd.value, rows_[j].est, r);
    }
    const std::string cause = watch_->check(in_step_, k - last_sample_cycle_, rd.last_error, rows_[k].est, r);
    if (cause.empty()) return;
    r.safety_stop = cause;
    r.stop_tick = static_cast<long>(in_step_);
    r.active_at_stop = (tel.state_flags & protocol::state::kOutputsActive) != 0;
    state_.safe = true;  // the next cycle's command is the safe one
    stop_seq_ = tel.seq;
    stop_cycle_ = k;
  }

  /// After a stop: the first telemetry reporting mode safe with outputs off ends the session; ticks_to_safe is
  /// counted in device ticks (telemetry sequence numbers) from the frame the decision was made on.
  void awaitSafe(const TelemetryFrame& tel, size_t k) {
    StepResult& r = results_[state_.step];
    if (tel.mode == protocol::Mode::kSafe && (tel.state_flags & protocol::state::kOutputsActive) == 0) {
      r.ticks_to_safe = static_cast<uint16_t>(tel.seq - stop_seq_);
      done_ = true;
    } else if (k - stop_cycle_ >= static_cast<size_t>(kSafeWaitCycles)) {
      done_ = true;
    }
  }

  void nextStep() {
    step_end_.push_back(rows_.size());
    in_step_ = 0;
    ++state_.step;
    progress_frac_.store(0.0, std::memory_order_relaxed);
    progress_step_.store(state_.step, std::memory_order_relaxed);
    if (state_.step >= plan_.steps.size()) {
      done_ = true;
      return;
    }
    watch_.emplace(plan_);
  }

  struct Slot {
    size_t first_cycle, cycles;
  };
  const Plan& plan_;
  const bool sim_instrument_;
  std::vector<StepResult> results_;
  std::vector<Slot> slots_;
  std::vector<CycleRow> rows_;
  std::vector<SampleRow> samples_;
  std::vector<size_t> step_end_;  ///< rows_ index one past each finished step
  std::vector<modbus::InstrumentReading> at_step_end_;  ///< the instrument's reading in each step's last cycle
  size_t est_index_ = 0, sp_index_ = 0;
  PlanState state_;
  std::optional<SafetyWatch> watch_;
  std::unique_ptr<modbus::InstrumentClient> inst_;
  modbus::InstrumentConfig instrument_cfg_;
  nlohmann::json link_, summary_;
  std::atomic<bool> started_{false};  ///< read by the progress thread
  bool done_ = false;
  size_t in_step_ = 0, last_sample_cycle_ = 0, stop_cycle_ = 0;
  uint64_t last_sample_ns_ = 0;
  uint16_t stop_seq_ = 0;
  std::atomic<size_t> progress_step_{0};
  std::atomic<double> progress_frac_{0.0};

  StepResult finishStep(size_t i, size_t begin, size_t end);
};

/// The frames of rows [begin, end): a row whose telemetry is not newer than the previous row's repeats it (a cycle
/// without new telemetry) and is dropped.
std::vector<CycleRow> framesOf(const std::vector<CycleRow>& rows, size_t begin, size_t end) {
  std::vector<CycleRow> out;
  for (size_t k = begin; k < end; ++k) {
    if (k > 0 && rows[k].seq == rows[k - 1].seq) continue;
    out.push_back(rows[k]);
  }
  return out;
}

/// How fast the device's clock ran against the host's over the frames (least squares of arrival time on device
/// time), in ppm: reported, not used — a clock that loses ticks (firmware-sim on a loaded machine) is not a line.
double clockDriftPpm(const std::vector<CycleRow>& frames) {
  if (frames.size() < 2) return 0.0;
  const double d0 = static_cast<double>(frames.front().dev_us) * 1e-3, h0 = static_cast<double>(frames.front().rx_ns) * 1e-6;
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (const CycleRow& f : frames) {
    const double x = static_cast<double>(f.dev_us) * 1e-3 - d0, y = static_cast<double>(f.rx_ns) * 1e-6 - h0;
    sx += x, sy += y, sxx += x * x, sxy += x * y;
  }
  const double n = static_cast<double>(frames.size());
  const double den = n * sxx - sx * sx;
  return den > 0 ? ((n * sxy - sx * sy) / den - 1.0) * 1e6 : 0.0;
}

/// Each frame's device tick on the host clock (ms): its device time plus the smallest (arrival − device time) over
/// the kClockWindow frames either side. A frame arrives its tick plus a transport delay that is never negative;
/// the least delay in a window is the link's own, the rest is queueing. A window, not one line through the
/// session: it follows a drifting crystal and a simulated clock that loses the ticks a loaded machine missed.
std::vector<double> tickTimesOnHost(const std::vector<CycleRow>& frames) {
  std::vector<double> off(frames.size()), out(frames.size());
  for (size_t j = 0; j < frames.size(); ++j) {
    off[j] = static_cast<double>(frames[j].rx_ns) * 1e-6 - static_cast<double>(frames[j].dev_us) * 1e-3;
  }
  for (size_t j = 0; j < frames.size(); ++j) {
    const size_t lo = j > kClockWindow ? j - kClockWindow : 0, hi = std::min(frames.size(), j + kClockWindow + 1);
    const double least = *std::min_element(off.begin() + static_cast<long>(lo), off.begin() + static_cast<long>(hi));
    out[j] = static_cast<double>(frames[j].dev_us) * 1e-3 + least;
  }
  return out;
}

/// The instrument's samples on the device's clock (ms since the step's first tick), given each tick's host time T:
/// between the two ticks whose host times enclose a sample's arrival. A delay is then in the device's own time, so a
/// simulated board whose clock loses the ticks a loaded machine delayed still shows its instrument's delay in ticks.
void samplesOnDeviceClock(const std::vector<double>& T, const std::vector<SampleRow>& samples, double tick_ms,
                          std::vector<double>& s_ms, std::vector<double>& v) {
  const size_t ticks = T.size();
  size_t at = 0;
  for (const SampleRow& smp : samples) {
    const double ms = static_cast<double>(smp.ns) * 1e-6;
    if (ticks == 0 || ms < T.front() || ms > T.back() + kMaxLagMs) continue;
    while (at + 1 < ticks && T[at + 1] <= ms) ++at;
    const double span = at + 1 < ticks ? T[at + 1] - T[at] : 0.0;
    const double frac = span > 0.0 ? std::min(1.0, (ms - T[at]) / span) : 0.0;
    s_ms.push_back(at + 1 < ticks ? (static_cast<double>(at) + frac) * tick_ms
                                  : static_cast<double>(ticks - 1) * tick_ms + (ms - T.back()));
    v.push_back(smp.value);
  }
}

/// Pearson correlation of the instrument's samples [i0, i1) against the estimate held at (sample time − lag_ms).
double correlationAt(const std::vector<double>& T, const std::vector<double>& est, const std::vector<double>& s,
                     const std::vector<double>& v, size_t i0, size_t i1, double lag_ms) {
  double n = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  size_t j = 0;
  for (size_t i = i0; i < i1; ++i) {
    const double q = s[i] - lag_ms;
    if (q < T.front() || q > T.back()) continue;
    while (j + 1 < T.size() && T[j + 1] <= q) ++j;
    const double x = v[i], y = est[j];
    if (!std::isfinite(x) || !std::isfinite(y)) continue;
    n += 1, sx += x, sy += y, sxx += x * x, syy += y * y, sxy += x * y;
  }
  if (n < 10) return std::nan("");
  const double cxy = sxy - sx * sy / n, cxx = sxx - sx * sx / n, cyy = syy - sy * sy / n;
  return cxx > 0 && cyy > 0 ? cxy / std::sqrt(cxx * cyy) : std::nan("");
}

/// The lag of the largest correlation on the search grid, refined by a parabola through it and its neighbours.
double bestLag(const std::vector<double>& T, const std::vector<double>& est, const std::vector<double>& s,
               const std::vector<double>& v, size_t i0, size_t i1, double max_lag_ms, double& corr) {
  std::vector<double> lags, c;
  for (double lag = -max_lag_ms / 4; lag <= max_lag_ms + 1e-9; lag += kLagStepMs) {
    lags.push_back(lag);
    c.push_back(correlationAt(T, est, s, v, i0, i1, lag));
  }
  size_t best = 0;
  for (size_t k = 1; k < c.size(); ++k) {
    if (std::isfinite(c[k]) && (!std::isfinite(c[best]) || c[k] > c[best])) best = k;
  }
  corr = c[best];
  double lag = lags[best];
  if (best > 0 && best + 1 < c.size() && std::isfinite(c[best - 1]) && std::isfinite(c[best + 1])) {
    const double den = c[best - 1] - 2 * c[best] + c[best + 1];
    if (den < 0) lag += 0.5 * kLagStepMs * (c[best - 1] - c[best + 1]) / den;
  }
  return lag;
}

std::vector<StepResult> BenchHooks::finish() {
  std::vector<StepResult> out;
  size_t begin = 0;
  bool stopped = false;
  for (size_t i = 0; i < plan_.steps.size(); ++i) {
    const Step& st = plan_.steps[i];
    const size_t end = i < step_end_.size() ? step_end_[i] : rows_.size();
    if (stopped || begin >= end) {
      StepResult r;
      r.name = st.name;
      r.kind = st.kind;
      r.skipped = stopped;
      r.error = stopped ? "not run: safety stop in step " + std::to_string(out.size()) + " (" + out.back().name + ")"
                        : "not run: the session ended before this step" +
                              (summary_.contains("link_error") ? " (" + summary_["link_error"].get<std::string>() + ")" : std::string());
      out.push_back(std::move(r));
      continue;
    }
    out.push_back(finishStep(i, begin, end));
    if (!out.back().safety_stop.empty()) stopped = true;
    begin = end;
  }
  return out;
}

StepResult BenchHooks::finishStep(size_t i, size_t begin, size_t end) {
  const Step& st = plan_.steps[i];
  StepResult r = std::move(results_[i]);
  r.name = st.name;
  r.kind = st.kind;
  r.unit = plan_.instrument.unit;
  if (end - begin < slots_[i].cycles && r.safety_stop.empty()) {
    r.error = "the session ended " + std::to_string(slots_[i].cycles - (end - begin)) + " cycles before the step's end" +
              (summary_.contains("link_error") ? " (" + summary_["link_error"].get<std::string>() + ")" : std::string());
  }
  // The step on the device's own clock: one entry per device tick; a tick whose telemetry never arrived is stale.
  const std::vector<CycleRow> frames = framesOf(rows_, begin, end);
  const double tick_us = 1e6 / (summary_.value("firmware_tick_hz", 1000.0) > 0 ? summary_.value("firmware_tick_hz", 1000.0) : 1000.0);
  const uint64_t dev_first = frames.empty() ? 0 : frames.front().dev_us;
  const size_t ticks = frames.empty() ? 0 : static_cast<size_t>(std::llround(static_cast<double>(frames.back().dev_us - dev_first) / tick_us)) + 1;
  if (ticks > 2 * frames.size() + 1000) {  // a device clock that jumped (a reset): nothing to put on one grid
    size_t j = 1;
    while (j < frames.size() && frames[j].dev_us - frames[j - 1].dev_us < 1000000u) ++j;
    char at[200] = "";
    if (j < frames.size()) {
      std::snprintf(at, sizeof at, "; at frame %zu: %llu us (seq %u) after %llu us (seq %u)", j,
                    static_cast<unsigned long long>(frames[j].dev_us), frames[j].seq,
                    static_cast<unsigned long long>(frames[j - 1].dev_us), frames[j - 1].seq);
    }
    r.error = "device: its clock jumped during the step (" + std::to_string(ticks) + " ticks for " +
              std::to_string(frames.size()) + " frames" + at + ")";
    return r;
  }
  StepSeries ser;
  ser.sp.assign(ticks, std::nan(""));
  ser.est.assign(ticks, std::nan(""));
  ser.inst.assign(ticks, std::nan(""));
  ser.stale.assign(ticks, 1);
  ser.excluded.assign(ticks, 0);
  ser.settle = static_cast<size_t>(std::lround(st.settle_s * 1e6 / tick_us));
  // T: each tick on the host clock (a tick without a frame: its neighbour's offset), never decreasing.
  std::vector<double> T(ticks, std::nan("")), est_held(ticks);
  const std::vector<double> frame_host_ms = tickTimesOnHost(frames);
  for (size_t j = 0; j < frames.size(); ++j) {
    const auto t = static_cast<size_t>(std::llround(static_cast<double>(frames[j].dev_us - dev_first) / tick_us));
    ser.sp[t] = frames[j].sp;
    ser.est[t] = frames[j].est;
    T[t] = frame_host_ms[j];
  }
  double held = 0.0;
  for (size_t t = 0; t < ticks; ++t) {
    if (!std::isfinite(T[t])) T[t] = T[t - 1] + tick_us * 1e-3;  // tick 0 always has its frame
    if (t > 0) T[t] = std::max(T[t], T[t - 1]);
    if (std::isfinite(ser.est[t])) held = ser.est[t];
    est_held[t] = held;
  }
  const double tick_ms = tick_us * 1e-3;
  std::vector<double> s_ms, v;
  samplesOnDeviceClock(T, samples_, tick_ms, s_ms, v);
  for (size_t t = 0; t < ticks; ++t) T[t] = static_cast<double>(t) * tick_ms;  // from here on: device time
  r.link = {{"device", plan_.device}, {"where", link_}, {"device_ticks", ticks}, {"frames", frames.size()},
            {"ticks_unseen", ticks - std::min(ticks, frames.size())},
            {"telemetry_hz", ticks > 1 ? static_cast<double>(frames.size()) * 1e6 / (static_cast<double>(ticks) * tick_us) : 0.0}};
  r.instrument_stats = modbus::readingStatsJson(instrument_cfg_, at_step_end_[i]);
  if (!r.safety_stop.empty()) {
    r.error = r.safety_stop;
    if (r.ticks_to_safe < 0) r.error += "; the device did not report its safe state";
    return r;  // cut short: nothing scored, as in lockstep
  }
  if (ticks < 100) {
    if (r.error.empty()) r.error = "device: too few telemetry frames to score";
    return r;
  }
  const Alignment a = alignInstrument(T, est_held, s_ms, v, kMaxLagMs);
  r.alignment = {{"delay_ms", a.delay_ms}, {"uncertainty_ms", a.uncertainty_ms}, {"correlation", a.correlation},
                 {"quarter_delay_ms", a.quarter_delay_ms}, {"quarter_correlation", a.quarter_correlation},
                 {"quarters_used", a.quarters_used}, {"clock_drift_ppm", clockDriftPpm(frames)},
                 {"ok", a.ok}};
  if (!a.ok) {
    if (r.error.empty()) r.error = "alignment: " + a.error;
    return r;
  }
  // Each tick gets the newest sample that shows it or an earlier tick (sample time − delay ≤ the tick), held while
  // it is young: two poll periods, as in lockstep.
  const double max_age_ms = std::max(2.0, 2000.0 / plan_.instrument.poll_hz);
  size_t si = 0;
  for (size_t t = 0; t < ticks; ++t) {
    while (si < s_ms.size() && s_ms[si] - a.delay_ms <= T[t]) ++si;
    if (si == 0 || !std::isfinite(ser.est[t])) continue;
    const double age = T[t] - (s_ms[si - 1] - a.delay_ms);
    ser.inst[t] = v[si - 1];
    ser.stale[t] = age > max_age_ms ? 1 : 0;
  }
  // A tick without telemetry has no estimate or setpoint of its own: it holds the previous ones (the chirp's
  // analysis needs an unbroken record) and is never scored (stale).
  for (size_t t = 1; t < ticks; ++t) {
    if (!std::isfinite(ser.est[t])) {
      ser.est[t] = ser.est[t - 1];
      ser.sp[t] = ser.sp[t - 1];
      ser.stale[t] = 1;
    }
  }
  const char* last_error = r.instrument_stats.is_object() && r.instrument_stats.contains("last_error") &&
                                   r.instrument_stats["last_error"].is_string()
                               ? r.instrument_stats["last_error"].get_ref<const std::string&>().c_str()
                               : "";
  const std::string keep_error = r.error;
  if (!scoreSeries(plan_, st, ser, last_error, r)) return r;
  if (!keep_error.empty() && r.error.empty()) r.error = keep_error;
  if (r.faults != 0 && r.error.empty()) r.error = "device latched faults during the step (bits " + std::to_string(r.faults) + ")";
  // The pair metrics are the lockstep runner's, over device ticks instead of rig steps: comparable when aligned,
  // on a whole record (no missing frame beyond the stale allowance).
  r.alignment["comparable_to_lockstep"] = r.error.empty();
  r.pass = r.error.empty() && std::all_of(r.checks.begin(), r.checks.end(), [](const Check& c) { return c.pass; });
  return r;
}

}  // namespace

Alignment alignInstrument(const std::vector<double>& T, const std::vector<double>& est, const std::vector<double>& s,
                          const std::vector<double>& v, double max_lag_ms) {
  Alignment a;
  if (T.size() < 100 || s.size() < 100) {
    a.error = "too few samples to align (" + std::to_string(s.size()) + " instrument samples, " + std::to_string(T.size()) + " ticks)";
    return a;
  }
  a.delay_ms = bestLag(T, est, s, v, 0, s.size(), max_lag_ms, a.correlation);
  // The uncertainty: how far the quarters of the step disagree (their sample standard deviation), at least the
  // search step. A quarter whose instrument does not follow the estimate (a held grasp's steady force: noise on
  // both sides) has no delay of its own and is left out; two quarters at least must remain.
  double m = 0, m2 = 0;
  for (size_t q = 0; q < 4; ++q) {
    double c = 0;
    const double d = bestLag(T, est, s, v, q * s.size() / 4, (q + 1) * s.size() / 4, max_lag_ms, c);
    a.quarter_delay_ms.push_back(d);
    a.quarter_correlation.push_back(c);
    if (!std::isfinite(c) || c < kMinCorrelation) continue;
    ++a.quarters_used;
    m += d;
    m2 += d * d;
  }
  const auto n = static_cast<double>(a.quarters_used);
  const double var = n > 1 ? (m2 - m * m / n) / (n - 1) : 0.0;
  a.uncertainty_ms = std::max(kLagStepMs, std::sqrt(std::max(0.0, var)));
  char buf[200];
  if (!std::isfinite(a.correlation) || a.correlation < kMinCorrelation) {
    std::snprintf(buf, sizeof buf, "the instrument and the device's estimate do not correlate (%.3f at the best delay, "
                  "%.2f needed): the step's excitation does not fix a delay", a.correlation, kMinCorrelation);
    a.error = buf;
    return a;
  }
  if (a.quarters_used < 2) {
    std::snprintf(buf, sizeof buf, "only %zu of the step's quarters follow the estimate (correlation %.2f or more): the "
                  "delay cannot be checked against a second part of the step", a.quarters_used, kMinCorrelation);
    a.error = buf;
    return a;
  }
  if (a.uncertainty_ms > kMaxUncertaintyMs) {
    std::snprintf(buf, sizeof buf, "the step's quarters disagree on the delay by %.2f ms (%.1f ms allowed): the excitation "
                  "does not fix it", a.uncertainty_ms, kMaxUncertaintyMs);
    a.error = buf;
    return a;
  }
  a.ok = true;
  return a;
}

std::string realtimeUnsupported(const Plan& plan) {
  if (!plan.noise) return "noise: false needs --lockstep (firmware-sim and a real device always have sensor noise)";
  for (size_t i = 0; i < plan.steps.size(); ++i) {
    const Step& st = plan.steps[i];
    const std::string w = "steps[" + std::to_string(i) + "]";
    if (st.kind == "pen-wall") {
      return w + ".kind: pen-wall runs in lockstep only (its hand schedule and wall truth are the lockstep rig's): use --lockstep";
    }
    if (st.instrument_hang_at_s >= 0 || st.instrument_lie_at_s >= 0) {
      return w + ": instrument_hang_at_s / instrument_lie_at_s are faults of the lockstep's own amplifier: use --lockstep "
             "(in real time, fail the instrument itself)";
    }
    if (plan.device.rfind("sim:", 0) == 0 && st.kind != plan.steps.front().kind && isGloveStep(st)) {
      return w + ".kind: firmware-sim's simulated hand runs one scenario for the whole session (close-open for "
             "glove-free-motion, grasp for glove-grasp): put " + st.kind + " in a plan of its own, or use --lockstep";
    }
    if (st.finger != plan.steps.front().finger) {
      return w + ".finger: in real time one instrument reads one finger for the whole plan (" +
             std::to_string(plan.steps.front().finger) + " in steps[0])";
    }
  }
  return {};
}

PlanResult runPlanOnDevice(const Plan& plan, const Progress& progress, const DeviceRunOptions& o) {
  PlanResult out;
  const uint64_t start = linux_hal::monotonicNs();
  const bool sim = plan.device.rfind("sim:", 0) == 0;
  const bool sim_instrument = sim && plan.sim_instrument;
  RunOptions opt;
  opt.device = plan.device;
  double total_s = 0;
  for (const Step& st : plan.steps) total_s += st.seconds;
  opt.seconds = total_s + 1.0;  // a backstop: the plan ends the session itself (stopRequested)
  opt.realtime = o.realtime;
  opt.seed = plan.seed;
  opt.firmware_sim = o.firmware_sim;
  // The simulated user (sim: devices): the glove's hand closes and opens, or reaches for and squeezes the ball.
  opt.scenario = plan.device_type != "glove5" ? "still" : (plan.steps.front().kind == "glove-grasp" ? "grasp" : "close-open");
  opt.mode = "transparent";
  if (sim_instrument) {
    const modbus::InstrumentConfig& c = plan.instrument;
    char map[240];
    std::snprintf(map, sizeof map, "unit_id=%u,table=%s,address=%u,type=%s,word_order=%s,scale=%.9g,offset=%.9g", c.unit_id,
                  c.table.c_str(), c.address, c.type.c_str(), c.word_order.c_str(), c.scale, c.offset);
    opt.sim_args = {"--instrument", c.transport == "rtu" ? "rtu" : "tcp:0", "--instrument-map", map};
    if (plan.device_type == "glove5") {
      opt.sim_args.insert(opt.sim_args.end(),
                          {"--instrument-signal", std::string("pad_force_") + kFingers[plan.steps.front().finger] + "_N"});
    }
    if (plan.sim_instrument_delay_ms > 0) {
      char d[32];
      std::snprintf(d, sizeof d, "%.9g", plan.sim_instrument_delay_ms);
      opt.sim_args.insert(opt.sim_args.end(), {"--instrument-delay-ms", d});
    }
  }
  // The simulated board runs under SCHED_FIFO below the session (the session runner does it for every real-time
  // sim: session), so the host machine's load does not starve its ticks and its amplifier. Measured without it beside
  // stress-ng --cpu 1: 4 800 overruns in 16 s and an instrument delay wandering 14-46 ms within a step.
  BenchHooks hooks(plan, sim_instrument);
  opt.hooks = &hooks;
  // Progress from a thread of its own: the session thread only stores two counters.
  std::atomic<bool> running{true};
  std::thread reporter([&] {
    size_t last = static_cast<size_t>(-1);
    while (running.load()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      const size_t i = hooks.progressStep();
      if (hooks.started() && i < plan.steps.size()) {
        progress(i, plan.steps.size(), plan.steps[i].name, hooks.progressFraction());
        last = i;
      }
    }
    if (last < plan.steps.size()) progress(last, plan.steps.size(), plan.steps[last].name, 1.0);
  });
  nlohmann::json summary;
  const int rc = runSession(opt, summary);
  running = false;
  reporter.join();
  if (!hooks.started()) {
    const std::string why = summary.value("error", std::string("the session did not start (exit ") + std::to_string(rc) + ")");
    for (const Step& st : plan.steps) {
      StepResult r;
      r.name = st.name;
      r.kind = st.kind;
      r.error = why;
      out.steps.push_back(std::move(r));
    }
  } else {
    out.steps = hooks.finish();
  }
  out.session = nlohmann::json::object();
  for (const char* k : {"link", "device_type", "firmware_build_id", "firmware_tick_hz", "realtime", "round_trip", "telemetry",
                        "commands", "cycles", "overruns", "link_error", "error"}) {
    if (summary.contains(k)) out.session[k] = summary[k];
  }
  out.session["exit_code"] = rc;
  out.pass = !out.steps.empty() && std::all_of(out.steps.begin(), out.steps.end(), [](const StepResult& s) { return s.pass; });
  out.wall_s = static_cast<double>(linux_hal::monotonicNs() - start) * 1e-9;
  return out;
}

}  // namespace phalanx::host::benchrun
