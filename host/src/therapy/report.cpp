#include "phalanx/host/design/svg.h"
#include "phalanx/host/therapy/report.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

#include "phalanx/host/metrics.h"
#include "phalanx/host/record/output_file.h"
#include "phalanx/host/session.h"
#include "phalanx/host/therapy/assessment_analysis.h"
#include "phalanx/host/therapy/device.h"
#include "phalanx/host/therapy/exercise.h"
#include "phalanx/host/therapy/guidance.h"

namespace phalanx::host::therapy {
namespace {

constexpr double kDeg = 180.0 / M_PI;
/// The same 5 Hz low-pass as the live ROM (therapy_controller.cpp): min/max of raw samples pick noise tails.
constexpr double kRomCutoffHz = 5.0;
/// Plots carry at most this many points per series (a 30-minute session has 1.8 M cycles).
constexpr std::size_t kMaxPlotPoints = 1500;

const auto& esc = design::markupEscape;

std::string fmt(double v, int digits = 2) {
  if (!std::isfinite(v)) return "–";
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

KinematicParams kinematicsFrom(const nlohmann::json& h) {
  KinematicParams k;
  if (!h.contains("kinematics") || !h["kinematics"].is_object()) return k;
  for (const auto& [ch, v] : h["kinematics"].items()) {
    if (!v.is_object()) continue;
    k.segment_lengths_mm.emplace_back(ch, std::array<double, 3>{v.value("p1_mm", 0.0), v.value("p2_mm", 0.0),
                                                                v.value("p3_mm", 0.0)});
  }
  return k;
}

/// Per-cycle quantities the report needs, extracted once.
struct Series {
  std::vector<double> t;
  std::vector<int> exercise;                       // ExerciseId per cycle (−1: not a therapy session)
  std::vector<std::vector<double>> flex;           // [joint][cycle], NaN when not measured
  std::vector<std::vector<double>> q, target, effort, effort_cmd;  // [channel][cycle]
  std::vector<uint16_t> faults;
  /// The device was locked or faulted this cycle (a latched fault, or still in safe/lock after one while the
  /// session commanded it to move): not exercise, so excluded from every exercise metric.
  std::vector<char> excluded;
};

bool holdingMode(uint8_t mode) {
  return mode == static_cast<uint8_t>(protocol::Mode::kSafe) || mode == static_cast<uint8_t>(protocol::Mode::kLock);
}

struct Layout {
  std::unique_ptr<TherapyDevice> device;
  std::string error;
};

Layout layoutFor(const record::SessionRecord& rec) {
  Layout l;
  if (!rec.header.is_object() || !rec.header.contains("device")) {
    l.error = "the record has no header (damaged)";
    return l;
  }
  l.device = makeTherapyDevice(rec.header["device"].get<std::string>(), kinematicsFrom(rec.header), l.error);
  return l;
}

Series extract(const record::SessionRecord& rec, TherapyDevice& dev) {
  Series s;
  const std::size_t nj = dev.jointCount(), nc = dev.channelCount();
  s.flex.assign(nj, {});
  s.q.assign(nc, {});
  s.target.assign(nc, {});
  s.effort.assign(nc, {});
  s.effort_cmd.assign(nc, {});
  std::vector<int> target_idx(nc, -1), cmd_idx(nc, -1);
  for (std::size_t c = 0; c < nc; ++c) {
    target_idx[c] = rec.auxIndex("target_" + dev.channelName(c) + "_rad");
    cmd_idx[c] = rec.auxIndex("effort_cmd_" + dev.channelName(c));
  }
  const int ex_idx = rec.auxIndex("exercise_id");
  TelemetryFrame tel;
  Observation obs{};
  const double nan = std::nan("");
  bool after_fault = false;
  for (const auto& c : rec.cycles) {
    tel.device_time_us = c.device_time_us;
    tel.mode = static_cast<protocol::Mode>(c.tel_mode);
    tel.fault_bits = c.fault_bits;
    tel.sample_count = c.sample_count;
    for (std::size_t i = 0; i < c.sample_count; ++i) tel.value[i] = c.sample[i];
    dev.observe(tel, obs);
    s.t.push_back(c.t_s);
    s.exercise.push_back(ex_idx >= 0 && ex_idx < c.aux_count ? static_cast<int>(c.aux[static_cast<std::size_t>(ex_idx)]) : -1);
    s.faults.push_back(c.fault_bits);
    // Locked after a fault: from the fault until the device moves again (its cleared fault's lock included).
    if (c.fault_bits != 0) after_fault = true;
    else if (!holdingMode(c.tel_mode)) after_fault = false;
    s.excluded.push_back(c.fault_bits != 0 || (after_fault && !holdingMode(c.cmd_mode)) ? 1 : 0);
    for (std::size_t j = 0; j < nj; ++j) s.flex[j].push_back(obs.joint_valid[j] ? obs.flexion_rad[j] : nan);
    for (std::size_t ch = 0; ch < nc; ++ch) {
      s.q[ch].push_back(obs.channel_valid[ch] ? obs.q_rad[ch] : nan);
      s.effort[ch].push_back(obs.effort[ch]);
      const auto aux = [&](int idx) {
        return idx >= 0 && idx < c.aux_count ? static_cast<double>(c.aux[static_cast<std::size_t>(idx)]) : nan;
      };
      s.target[ch].push_back(aux(target_idx[ch]));
      s.effort_cmd[ch].push_back(cmd_idx[ch] >= 0 ? aux(cmd_idx[ch]) : dev.effortFromSetpoint(ch, c.setpoint[ch]));
    }
  }
  return s;
}

std::string svgPlot(const std::string& title, const std::string& y_label, const std::vector<double>& t,
                    const std::vector<std::pair<std::string, const std::vector<double>*>>& series) {
  static const char* kColors[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#17becf", "#7f7f7f"};
  const double W = 760, H = 220, L = 60, R = 130, T = 24, B = 32;
  double y0 = 1e300, y1 = -1e300;
  for (const auto& [n, v] : series) {
    for (double y : *v) {
      if (std::isfinite(y)) {
        y0 = std::min(y0, y);
        y1 = std::max(y1, y);
      }
    }
  }
  if (t.empty() || y0 > y1) return "<p><em>" + esc(title) + ": no data</em></p>";
  if (y1 - y0 < 1e-9) {
    y0 -= 1.0;
    y1 += 1.0;
  }
  const double pad = 0.05 * (y1 - y0);
  y0 -= pad;
  y1 += pad;
  const double t0 = t.front(), t1 = std::max(t.back(), t.front() + 1e-6);
  auto X = [&](double x) { return L + (x - t0) / (t1 - t0) * (W - L - R); };
  auto Y = [&](double y) { return T + (y1 - y) / (y1 - y0) * (H - T - B); };
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='" << H << "' viewBox='0 0 " << W << " "
    << H << "' role='img' aria-label='" << esc(title) << "'>";
  o << "<rect x='" << L << "' y='" << T << "' width='" << W - L - R << "' height='" << H - T - B
    << "' fill='#fff' stroke='#999'/>";
  o << "<text x='" << L << "' y='16' font-size='13' font-weight='bold'>" << esc(title) << "</text>";
  for (int i = 0; i <= 4; ++i) {
    const double y = y0 + (y1 - y0) * i / 4.0;
    o << "<line x1='" << L << "' x2='" << W - R << "' y1='" << fmt(Y(y), 1) << "' y2='" << fmt(Y(y), 1)
      << "' stroke='#eee'/><text x='" << L - 4 << "' y='" << fmt(Y(y) + 4, 1) << "' font-size='10' text-anchor='end'>"
      << fmt(y, std::fabs(y1 - y0) < 10 ? 2 : 0) << "</text>";
    const double x = t0 + (t1 - t0) * i / 4.0;
    o << "<text x='" << fmt(X(x), 1) << "' y='" << H - B + 14 << "' font-size='10' text-anchor='middle'>" << fmt(x, 1)
      << "</text>";
  }
  o << "<text x='" << (L + W - R) / 2 << "' y='" << H - 4 << "' font-size='10' text-anchor='middle'>time (s)</text>";
  o << "<text x='12' y='" << (T + H - B) / 2 << "' font-size='10' transform='rotate(-90 12 " << (T + H - B) / 2
    << ")' text-anchor='middle'>" << esc(y_label) << "</text>";
  const std::size_t stride = std::max<std::size_t>(1, t.size() / kMaxPlotPoints);
  std::size_t k = 0;
  for (const auto& [name, v] : series) {
    const char* color = kColors[k % 8];
    o << "<polyline fill='none' stroke='" << color << "' stroke-width='1.2' points='";
    bool any = false;
    for (std::size_t i = 0; i < t.size() && i < v->size(); i += stride) {
      if (!std::isfinite((*v)[i])) continue;
      o << fmt(X(t[i]), 1) << "," << fmt(Y((*v)[i]), 1) << " ";
      any = true;
    }
    o << "'/>";
    if (any) {
      const double ly = T + 10 + 14 * static_cast<double>(k);
      o << "<line x1='" << W - R + 8 << "' x2='" << W - R + 24 << "' y1='" << ly << "' y2='"
        << ly << "' stroke='" << color << "' stroke-width='2'/><text x='" << W - R + 28 << "' y='"
        << ly + 4 << "' font-size='10'>" << esc(name) << "</text>";
    }
    ++k;
  }
  o << "</svg>";
  return o.str();
}

/// Horizontal range bars per joint: previous session (grey) above this one (blue).
std::string svgRom(const nlohmann::json& rom, const nlohmann::json& prev) {
  const double W = 760, L = 110, R = 20, row = 26;
  const double H = 30 + row * static_cast<double>(rom.size());
  double lo = -30, hi = 120;
  for (const auto& [j, r] : rom.items()) {
    lo = std::min(lo, r[0].get<double>());
    hi = std::max(hi, r[1].get<double>());
  }
  auto X = [&](double d) { return L + (d - lo) / (hi - lo) * (W - L - R); };
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='" << H << "' role='img' aria-label='range of motion'>";
  for (int d = static_cast<int>(std::ceil(lo / 30.0)) * 30; d <= hi; d += 30) {
    o << "<line x1='" << fmt(X(d), 1) << "' x2='" << fmt(X(d), 1) << "' y1='10' y2='" << H - 14 << "' stroke='#eee'/>"
      << "<text x='" << fmt(X(d), 1) << "' y='" << H - 2 << "' font-size='10' text-anchor='middle'>" << d << "°</text>";
  }
  int i = 0;
  for (const std::string& j : anatomicalKeys(rom)) {
    const nlohmann::json& r = rom[j];
    const double y = 12 + row * i++;
    o << "<text x='" << L - 6 << "' y='" << y + 13 << "' font-size='11' text-anchor='end'>" << esc(j) << "</text>";
    if (prev.is_object() && prev.contains(j)) {
      o << "<rect x='" << fmt(X(prev[j][0].get<double>()), 1) << "' y='" << y << "' width='"
        << fmt(X(prev[j][1].get<double>()) - X(prev[j][0].get<double>()), 1) << "' height='8' fill='#bbb'/>";
    }
    o << "<rect x='" << fmt(X(r[0].get<double>()), 1) << "' y='" << y + 9 << "' width='"
      << fmt(X(r[1].get<double>()) - X(r[0].get<double>()), 1) << "' height='10' fill='#1f77b4'/>";
  }
  o << "</svg>";
  return o.str();
}

/// Linear interpolation of (t, y) at time x (t ascending); NaN outside [t.front(), t.back()].
double interpolate(const std::vector<double>& t, const std::vector<double>& y, double x) {
  if (t.empty() || x < t.front() || x > t.back()) return std::nan("");
  const auto it = std::lower_bound(t.begin(), t.end(), x);
  const std::size_t i = static_cast<std::size_t>(it - t.begin());
  if (i == 0) return y[0];
  const double a = (x - t[i - 1]) / (t[i] - t[i - 1]);
  return y[i - 1] + a * (y[i] - y[i - 1]);
}

/// 001 Table 2 / 000 Table 4: Pearson r between the joint trajectory with the device (assessment phases of the
/// record) and the device-free reference at the same times.
nlohmann::json transparencyR(const TherapyDevice& dev, const Series& s, const TransparencyReference& ref) {
  nlohmann::json out = nlohmann::json::object();
  const int kAssess = static_cast<int>(ExerciseId::kAssessment);
  for (const auto& [name, y] : ref.joints_deg) {
    const int j = dev.jointIndex(name);
    if (j < 0) continue;
    std::vector<double> with, without;
    for (std::size_t i = 0; i < s.t.size(); ++i) {
      if (s.exercise[i] != kAssess || s.excluded[i] || !std::isfinite(s.flex[static_cast<std::size_t>(j)][i])) continue;
      const double r = interpolate(ref.t_s, y, s.t[i]);
      if (!std::isfinite(r)) continue;
      with.push_back(s.flex[static_cast<std::size_t>(j)][i] * kDeg);
      without.push_back(r);
    }
    if (with.size() < 2) continue;
    const double r = pearson(without, with);
    double sq = 0.0;
    for (std::size_t i = 0; i < with.size(); ++i) sq += (with[i] - without[i]) * (with[i] - without[i]);
    out[name] = {{"pearson_r", std::isfinite(r) ? nlohmann::json(r) : nlohmann::json(nullptr)},
                 {"rms_difference_deg", std::sqrt(sq / static_cast<double>(with.size()))},
                 {"samples", with.size()}};
  }
  return out;
}

/// A therapist request of the record in words: (what, details), e.g. ("exercise changed to assistance",
/// "period_s 3, deadband_deg 8").
std::pair<std::string, std::string> describeRequest(const nlohmann::json& e, const std::string& unit) {
  const std::string kind = e.value("kind", std::string());
  auto list = [](const nlohmann::json& obj, const std::string& suffix) {
    std::string out;
    if (!obj.is_object()) return out;
    for (const std::string& k : anatomicalKeys(obj)) {
      const nlohmann::json& v = obj[k];
      out += (out.empty() ? "" : ", ") + k + " " +
             (v.is_number() ? humanNumber(v.get<double>(), 3) + suffix : v.is_string() ? v.get<std::string>() : v.dump());
    }
    return out;
  };
  if (kind == "api-exercise") {
    const std::string p = list(e.value("params", nlohmann::json::object()), "");
    return {"exercise changed to " + e.value("exercise", std::string("?")), p.empty() ? "default parameters" : p};
  }
  if (kind == "api-limits") return {"effort limit lowered", list(e.value("effort_max", nlohmann::json::object()), " " + unit)};
  if (kind == "api-clear-faults") return {"reset faults (ClearFaults sent)", ""};
  if (kind == "api-pause") return {"paused (zero effort; the plan's clock stopped)", ""};
  if (kind == "api-resume") return {"resumed", ""};
  nlohmann::json rest = e;
  rest.erase("t_s");
  rest.erase("kind");
  return {kind.substr(kind.rfind("api-", 0) == 0 ? 4 : 0), rest.empty() ? "" : rest.dump()};
}

/// The session plan of the record's header with each step's outcome (its plan-step-ended event): done with its
/// repetitions, counted seconds and what ended it, or "not done" (the session stopped before).
nlohmann::json planOutcome(const record::SessionRecord& rec) {
  nlohmann::json steps = nlohmann::json::array();
  if (!rec.header["plan"].is_array()) return steps;
  for (const auto& st : rec.header["plan"]) {
    nlohmann::json j = st;
    j["done"] = false;
    steps.push_back(std::move(j));
  }
  for (const auto& e : rec.events) {
    if (e.value("kind", std::string()) != "plan-step-ended") continue;
    const std::size_t i = e.value("step", std::size_t{0});
    if (i >= steps.size()) continue;
    steps[i]["done"] = true;
    steps[i]["repetitions_done"] = e.value("repetitions", 0);
    steps[i]["counted_s"] = e.value("counted_s", 0.0);
    steps[i]["ended_by"] = e.value("ended_by", std::string());
    steps[i]["end_t_s"] = e.value("t_s", 0.0);
  }
  return steps;
}

std::vector<char> phaseMask(const Series& s, ExerciseId id) {
  std::vector<char> in(s.t.size(), 0);
  for (std::size_t i = 0; i < s.t.size(); ++i) in[i] = s.exercise[i] == static_cast<int>(id) && !s.excluded[i];
  return in;
}

bool any(const std::vector<char>& v) { return std::find(v.begin(), v.end(), 1) != v.end(); }

nlohmann::json num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

/// The tardieu phase's figures; the stretched channel is the one with a target in it.
nlohmann::json tardieuMetrics(const TherapyDevice& dev, const Series& s, const std::vector<char>& in) {
  for (std::size_t c = 0; c < dev.channelCount(); ++c) {
    bool has_target = false;
    for (std::size_t i = 0; i < s.t.size() && !has_target; ++i) has_target = in[i] && std::isfinite(s.target[c][i]);
    if (!has_target) continue;
    TardieuFigures f;
    if (std::string err = analyseTardieu(s.t, s.q[c], s.effort[c], s.target[c], in, f); !err.empty()) {
      return {{"channel", dev.channelName(c)}, {"error", err}};
    }
    nlohmann::json st = nlohmann::json::array();
    for (const auto& x : f.stretches) {
      // Nominal velocity to the nearest 5°/s (the target is a float in the record: 210 reads as 208.x).
      st.push_back({{"nominal_deg_s", 5 * static_cast<int>(std::lround(x.nominal_rad_s * kDeg / 5.0))},
                    {"velocity_deg_s", num(x.velocity_rad_s * kDeg)}, {"resistance", num(x.resistance)},
                    {"catch_deg", num(x.catch_rad * kDeg)}, {"reflex", num(x.reflex)}});
    }
    return {{"channel", dev.channelName(c)}, {"stretches", st}, {"catch_deg", num(f.catch_rad * kDeg)},
            {"threshold_deg_s", num(f.threshold_rad_s * kDeg)}, {"gain_per_rad_s", num(f.gain_per_rad_s)},
            {"fit_residual", f.residual}};
  }
  return {{"error", "tardieu: no channel had a target"}};
}

/// Instrumented assessments (assessment_analysis.h) of the phases present.
nlohmann::json instrumentedMetrics(const TherapyDevice& dev, const Series& s) {
  nlohmann::json out = nlohmann::json::object();
  const std::vector<char> tardieu = phaseMask(s, ExerciseId::kTardieu), passive = phaseMask(s, ExerciseId::kPassiveRom),
                          force = phaseMask(s, ExerciseId::kMaxForce);
  if (any(tardieu)) out["tardieu"] = tardieuMetrics(dev, s, tardieu);
  if (any(passive)) {
    for (std::size_t j = 0; j < dev.jointCount(); ++j) {
      const PassiveRomFigures f = analysePassiveRom(s.flex[j], s.effort_cmd[dev.jointChannel(j)], passive);
      out["passive_rom_deg"][dev.jointName(j)] = {{"extension", num(f.extension_rad * kDeg)}, {"flexion", num(f.flexion_rad * kDeg)}};
    }
  }
  if (any(force)) {
    for (std::size_t c = 0; c < dev.channelCount(); ++c) out["max_force"][dev.channelName(c)] = num(analyseMaxForce(s.t, s.effort[c], force));
  }
  return out;
}

nlohmann::json metricsOf(const record::SessionRecord& rec, TherapyDevice& dev, Series& s,
                         const TransparencyReference* reference) {
  nlohmann::json m;
  m["device"] = dev.name();
  m["effort_unit"] = dev.effortUnit();
  m["patient"] = rec.header.value("patient", std::string());
  m["start_utc"] = rec.header.value("start_utc", std::string());
  m["cycles"] = rec.cycles.size();
  m["duration_s"] = s.t.empty() ? 0.0 : s.t.back() - s.t.front();
  m["complete"] = rec.complete();
  m["torn_tail"] = rec.torn_tail;
  m["damaged_records"] = rec.bad_records;
  // Exercise segments.
  nlohmann::json segs = nlohmann::json::array();
  for (std::size_t i = 0; i < s.t.size(); ++i) {
    if (i == 0 || s.exercise[i] != s.exercise[i - 1]) {
      segs.push_back({{"exercise", s.exercise[i] < 0 ? std::string(rec.header.value("exercise", std::string("?")))
                                                     : exerciseName(static_cast<ExerciseId>(s.exercise[i]))},
                      {"start_s", s.t[i]}, {"end_s", s.t[i]}});
    }
    segs.back()["end_s"] = s.t[i];
  }
  m["exercises"] = segs;
  // Locked / faulted periods: listed, and left out of every exercise metric below.
  nlohmann::json excl = nlohmann::json::array();
  double excluded_s = 0.0;
  std::size_t excluded_cycles = 0;
  for (std::size_t i = 0; i < s.t.size(); ++i) {
    if (!s.excluded[i]) continue;
    ++excluded_cycles;
    if (i > 0) excluded_s += s.t[i] - s.t[i - 1];
    if (i == 0 || !s.excluded[i - 1]) excl.push_back({{"start_s", s.t[i]}, {"end_s", s.t[i]}, {"faults", faultList(s.faults[i])}});
    excl.back()["end_s"] = s.t[i];
    if (s.faults[i] != 0 && excl.back()["faults"] == "none") excl.back()["faults"] = faultList(s.faults[i]);
  }
  m["excluded_periods"] = excl;
  m["excluded_s"] = excluded_s;
  m["excluded_cycles"] = excluded_cycles;
  const int kAssess = static_cast<int>(ExerciseId::kAssessment);
  const bool has_assessment = std::find(s.exercise.begin(), s.exercise.end(), kAssess) != s.exercise.end();
  m["rom_source"] = has_assessment ? "assessment" : "whole session (no assessment in this session)";
  // ROM per joint (deg), from the 5 Hz low-passed angle.
  nlohmann::json rom = nlohmann::json::object();
  for (std::size_t j = 0; j < dev.jointCount(); ++j) {
    double lp = std::nan(""), lo = 1e300, hi = -1e300, prev_t = 0.0;
    for (std::size_t i = 0; i < s.t.size(); ++i) {
      const double x = s.flex[j][i];
      if (!std::isfinite(x)) continue;
      const double dt = std::isfinite(lp) ? std::max(s.t[i] - prev_t, 0.0) : 0.0;
      const double a = dt / (dt + 1.0 / (2.0 * M_PI * kRomCutoffHz));
      lp = std::isfinite(lp) ? lp + a * (x - lp) : x;
      prev_t = s.t[i];
      if ((has_assessment && s.exercise[i] != kAssess) || s.excluded[i]) continue;
      lo = std::min(lo, lp);
      hi = std::max(hi, lp);
    }
    if (lo <= hi) rom[dev.jointName(j)] = {lo * kDeg, hi * kDeg};
  }
  m["rom_deg"] = rom;
  m["instrumented"] = instrumentedMetrics(dev, s);
  // Tracking (assistance, playback): RMS error and Pearson r between the target and the channel coordinate.
  nlohmann::json tracking = nlohmann::json::object(), transparency = nlohmann::json::object(),
                 effort = nlohmann::json::object();
  for (std::size_t c = 0; c < dev.channelCount(); ++c) {
    std::vector<double> tg, q;
    double sq = 0.0, peak = 0.0, peak_cmd = 0.0, free_sq = 0.0, free_peak = 0.0;
    long n_free = 0;
    double tracked_s = 0.0;
    for (std::size_t i = 0; i < s.t.size(); ++i) {
      peak = std::max(peak, std::fabs(s.effort[c][i]));
      if (std::isfinite(s.effort_cmd[c][i])) peak_cmd = std::max(peak_cmd, std::fabs(s.effort_cmd[c][i]));
      const int ex = s.exercise[i];
      if (s.excluded[i]) continue;  // peaks above include them: a force that latched a fault must show
      if ((ex == static_cast<int>(ExerciseId::kAssistance) || ex == static_cast<int>(ExerciseId::kPlayback)) &&
          std::isfinite(s.target[c][i]) && std::isfinite(s.q[c][i])) {
        tg.push_back(s.target[c][i]);
        q.push_back(s.q[c][i]);
        if (i > 0) tracked_s += s.t[i] - s.t[i - 1];
      }
      if (ex == kAssess) {
        free_sq += s.effort[c][i] * s.effort[c][i];
        free_peak = std::max(free_peak, std::fabs(s.effort[c][i]));
        ++n_free;
      }
    }
    for (std::size_t i = 0; i < tg.size(); ++i) sq += (tg[i] - q[i]) * (tg[i] - q[i]);
    if (!tg.empty()) {
      const double r = pearson(tg, q);
      tracking[dev.channelName(c)] = {{"rms_error_deg", std::sqrt(sq / static_cast<double>(tg.size())) * kDeg},
                                      {"pearson_r", std::isfinite(r) ? nlohmann::json(r) : nlohmann::json(nullptr)},
                                      {"seconds", tracked_s}};
    }
    if (n_free > 0) {
      transparency[dev.channelName(c)] = {{"interaction_rms", std::sqrt(free_sq / static_cast<double>(n_free))},
                                          {"interaction_peak", free_peak}};
    }
    effort[dev.channelName(c)] = {{"peak_measured", peak}, {"peak_command", peak_cmd}};
  }
  m["tracking"] = tracking;
  m["transparency"] = transparency;
  if (reference != nullptr) m["transparency_r"] = transparencyR(dev, s, *reference);
  m["effort"] = effort;
  // Faults and other events.
  nlohmann::json faults = nlohmann::json::array();
  uint16_t seen = 0;
  for (std::size_t i = 0; i < s.faults.size(); ++i) {
    if (s.faults[i] != 0 && (i == 0 || s.faults[i] != s.faults[i - 1])) {
      faults.push_back({{"t_s", s.t[i]}, {"faults", faultList(s.faults[i])}});
    }
    seen |= s.faults[i];
  }
  m["faults"] = faults;
  m["faults_seen"] = faultList(seen);
  long limit_events = 0, gaps = 0;
  nlohmann::json requests = nlohmann::json::array();
  for (const auto& e : rec.events) {
    const std::string kind = e.value("kind", std::string());
    if (kind == "limit-active") ++limit_events;
    if (kind == "record-gap") gaps = e.value("cycles_dropped_total", 0L);
    if (kind.rfind("api-", 0) == 0) requests.push_back(e);
  }
  m["limit_onsets"] = limit_events;
  m["record_cycles_dropped"] = gaps;
  m["therapist_requests"] = requests;
  if (rec.header.is_object() && rec.header.contains("plan")) m["plan"] = planOutcome(rec);
  return m;
}

}  // namespace

std::string loadTransparencyReference(const std::string& path, TransparencyReference& out) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) return path + ": not a regular file";
  std::ifstream in(path);
  if (!in) return path + ": cannot read";
  TransparencyReference ref;
  std::string line;
  int line_no = 0;
  std::vector<std::string> cols;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
    const std::string where = path + ":" + std::to_string(line_no) + ": ";
    if (cols.empty()) {
      cols = cells;
      if (cols.empty() || cols[0] != "t_s") return where + "the header must start with t_s";
      for (std::size_t i = 1; i < cols.size(); ++i) {
        const std::string& c = cols[i];
        if (c.size() < 5 || c.compare(c.size() - 4, 4, "_deg") != 0) return where + "column '" + c + "' is not <joint>_deg";
        ref.joints_deg.push_back({c.substr(0, c.size() - 4), {}});
      }
      continue;
    }
    if (cells.size() != cols.size()) return where + "expected " + std::to_string(cols.size()) + " values";
    std::vector<double> v(cells.size());
    for (std::size_t i = 0; i < cells.size(); ++i) {
      char* end = nullptr;
      v[i] = std::strtod(cells[i].c_str(), &end);
      if (end == cells[i].c_str() || *end != 0 || !std::isfinite(v[i])) return where + "'" + cells[i] + "' is not a finite number";
    }
    if (!ref.t_s.empty() && v[0] <= ref.t_s.back()) return where + "t_s must increase";
    ref.t_s.push_back(v[0]);
    for (std::size_t i = 1; i < v.size(); ++i) ref.joints_deg[i - 1].second.push_back(v[i]);
  }
  if (ref.t_s.size() < 2) return path + ": fewer than two samples";
  out = std::move(ref);
  return {};
}

nlohmann::json sessionMetrics(const record::SessionRecord& rec, const TransparencyReference* reference) {
  Layout l = layoutFor(rec);
  if (!l.device) return {{"error", l.error}};
  Series s = extract(rec, *l.device);
  return metricsOf(rec, *l.device, s, reference);
}

namespace {
/// Every instrumented-assessment figure with its repeatability (ICC(2,1), MDC95) beside it.
std::string instrumentedHtml(const nlohmann::json& m, const nlohmann::json& rep, const std::string& unit) {
  const auto figures = assessmentFigures(m);
  std::ostringstream h;
  h << "<h2>Assessment figures and their repeatability</h2><p class='note'>ICC(2,1): Shrout &amp; Fleiss two-way "
       "random, absolute agreement, single measures; MDC95 = 1.96·√2·SEM, SEM = SD·√(1 − ICC): a change smaller than "
       "the MDC95 between two sessions is within the measurement's own repeatability. "
    << (rep.is_object() ? "Repeatability from " + esc(rep.value("source", std::string("the repeatability file"))) + "."
                        : "No repeatability file given (phalanx record report --repeatability FILE): ICC and MDC "
                          "unknown.")
    << "</p>";
  const nlohmann::json in = m.value("instrumented", nlohmann::json::object());
  if (in.contains("tardieu") && in["tardieu"].contains("error")) {
    h << "<p class='warn'>Tardieu test not analysed: " << esc(in["tardieu"]["error"].get<std::string>()) << "</p>";
  }
  h << "<table><tr><th>figure</th><th>value</th><th>unit</th><th>ICC(2,1)</th><th>MDC95</th></tr>";
  const nlohmann::json none = nlohmann::json::object();
  const nlohmann::json& rf = rep.is_object() ? rep["figures"] : none;
  for (const auto& [name, v] : figures) {
    h << "<tr><td>" << esc(name) << "</td><td>" << fmt(v, 3) << "</td><td>" << esc(figureUnit(name, unit)) << "</td>";
    if (rf.contains(name)) h << "<td>" << fmt(rf[name]["icc"].get<double>(), 3) << "</td><td>" << fmt(rf[name]["mdc95"].get<double>(), 3) << "</td>";
    else h << "<td>–</td><td>–</td>";
    h << "</tr>";
  }
  h << "</table>";
  return h.str();
}

/// The header's patient id ("" for a session without a profile).
std::string recordPatient(const record::SessionRecord& rec) {
  return rec.header.is_object() && rec.header.contains("patient") && rec.header["patient"].is_string()
             ? rec.header["patient"].get<std::string>()
             : std::string();
}
}  // namespace

std::string writeReport(const std::string& record_path, const std::string& previous_path, const std::string& html_path,
                        const std::function<void(const std::string&)>& progress, const std::string& reference_path,
                        const std::string& repeatability_path) {
  auto say = [&](const std::string& m) {
    if (progress) progress(m);
  };
  for (const std::string* input : {&record_path, &previous_path, &reference_path, &repeatability_path}) {
    if (input->empty()) continue;
    if (std::string err = record::refuseSameFile(*input, html_path); !err.empty()) return err;
  }
  say("reading " + record_path);
  record::SessionRecord rec;
  if (std::string err = record::readRecord(record_path, rec); !err.empty()) return err;
  Layout l = layoutFor(rec);
  if (!l.device) return record_path + ": " + l.error;
  TransparencyReference reference;
  if (!reference_path.empty()) {
    say("reading the device-free reference " + reference_path);
    if (std::string err = loadTransparencyReference(reference_path, reference); !err.empty()) return err;
  }
  nlohmann::json rep;
  if (!repeatability_path.empty()) {
    say("reading the repeatability file " + repeatability_path);
    if (std::string err = loadRepeatability(repeatability_path, rep); !err.empty()) return err;
  }
  say("computing metrics over " + std::to_string(rec.cycles.size()) + " cycles");
  Series s = extract(rec, *l.device);
  const nlohmann::json m = metricsOf(rec, *l.device, s, reference_path.empty() ? nullptr : &reference);
  nlohmann::json prev;
  if (!previous_path.empty()) {
    say("reading the previous session " + previous_path);
    record::SessionRecord p;
    if (record::readRecord(previous_path, p).empty()) {
      const std::string mine = recordPatient(rec), theirs = recordPatient(p);
      if (mine != theirs) {
        return "the previous record " + previous_path + " is of patient '" + theirs + "', " + record_path +
               " of patient '" + mine + "': not compared";
      }
      prev = sessionMetrics(p);
      if (prev.contains("error")) prev = nullptr;
    }
  }
  say("writing " + html_path);
  const TherapyDevice& dev = *l.device;
  const std::string unit = dev.effortUnit();
  std::ostringstream h;
  h << "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>Phalanx session report</title><style>"
       "body{font-family:sans-serif;max-width:800px;margin:1em auto;color:#222}table{border-collapse:collapse;margin:.5em 0}"
       "td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}th{background:#f4f4f4}td:first-child,th:first-child"
       "{text-align:left}.warn{color:#b00}.note{color:#555;font-size:90%}"
       ".better{color:#176317}.worse{color:#b00}.same{color:#555}td.text{text-align:left;white-space:normal}"
       ".excluded{background:#fff3f3;border:1px solid #e99;padding:.3em .6em}</style></head><body>";
  h << "<h1>Session report</h1><table><tr><th>patient</th><td>" << esc(m.value("patient", std::string("–")))
    << "</td></tr><tr><th>device</th><td>" << esc(m["device"].get<std::string>()) << "</td></tr><tr><th>start (UTC)</th><td>"
    << esc(m["start_utc"].get<std::string>()) << "</td></tr><tr><th>duration</th><td>" << fmt(m["duration_s"].get<double>(), 1)
    << " s</td></tr><tr><th>record</th><td>" << esc(record_path) << "</td></tr></table>";
  if (!rec.complete()) {
    h << "<p class='warn'>The record has no end marker: the daemon stopped without closing the session (crash or power "
         "loss). Everything up to the last "
      << (rec.torn_tail ? "complete " : "") << "cycle is included.</p>";
  }
  if (rec.bad_records > 0) h << "<p class='warn'>" << rec.bad_records << " damaged record(s) were skipped.</p>";
  h << "<h2>Exercises</h2><table><tr><th>exercise</th><th>from (s)</th><th>to (s)</th></tr>";
  for (const auto& e : m["exercises"]) {
    h << "<tr><td>" << esc(e["exercise"].get<std::string>()) << "</td><td>" << fmt(e["start_s"].get<double>(), 1)
      << "</td><td>" << fmt(e["end_s"].get<double>(), 1) << "</td></tr>";
  }
  h << "</table>";
  if (m.contains("plan")) {
    h << "<h2>Session plan</h2><p class='note'>Each step runs for its duration in session time (paused, faulted or "
         "locked time does not count) or until its repetitions are done, whichever comes first. A repetition is one "
         "flex-extend cycle of the counted channel between the thresholds shown.</p><table><tr><th>step</th>"
         "<th>exercise</th><th>duration (s)</th><th>repetitions</th><th>channel, thresholds (°)</th><th>outcome</th></tr>";
    int i = 0;
    for (const auto& st : m["plan"]) {
      const std::string what = st.value("exercise", std::string()) +
                               (st.contains("preset") ? " (preset " + st.value("preset", std::string()) + ")" : "");
      const nlohmann::json rr = st.value("rep_range_deg", nlohmann::json::array());
      h << "<tr><td>" << ++i << "</td><td class='text'>" << esc(what) << "</td><td>" << fmt(st.value("duration_s", 0.0), 1)
        << "</td><td>" << st.value("repetitions", 0) << "</td><td class='text'>" << esc(st.value("channel", std::string()))
        << (rr.size() == 2 ? " " + fmt(rr[0].get<double>(), 0) + " / " + fmt(rr[1].get<double>(), 0) : "")
        << "</td><td class='text'>";
      if (st.value("done", false)) {
        h << "done: " << st.value("repetitions_done", 0) << " repetitions in " << fmt(st.value("counted_s", 0.0), 1)
          << " s (" << (st.value("ended_by", std::string()) == "repetitions" ? "target reached" : "its duration") << ")";
      } else {
        h << "<span class='warn'>not done</span> (the session ended before)";
      }
      h << "</td></tr>";
    }
    h << "</table>";
  }
  if (m["excluded_s"].get<double>() > 0.0) {
    h << "<div class='excluded'><b>" << fmt(m["excluded_s"].get<double>(), 1)
      << " s excluded from every exercise metric below</b> (range of motion, transparency, tracking): the device "
         "was locked or faulted then, so the hand was not exercising. Peak efforts include these periods. "
         "<table><tr><th>from (s)</th><th>to (s)</th><th>faults</th></tr>";
    for (const auto& e : m["excluded_periods"]) {
      h << "<tr><td>" << fmt(e["start_s"].get<double>(), 1) << "</td><td>" << fmt(e["end_s"].get<double>(), 1)
        << "</td><td>" << esc(e["faults"].get<std::string>()) << "</td></tr>";
    }
    h << "</table></div>";
  }
  // Range of motion.
  const nlohmann::json prom = prev.is_object() && prev.contains("rom_deg") ? prev["rom_deg"] : nlohmann::json();
  h << "<h2>Active range of motion</h2><p class='note'>Joint flexion in degrees (flexion positive), measured during "
    << esc(m["rom_source"].get<std::string>()) << "; 5 Hz low-passed."
    << (prom.is_object() ? " Grey bars: previous session." : " No previous session to compare with.") << "</p>";
  h << svgRom(m["rom_deg"], prom);
  h << "<table><tr><th>joint</th><th>min</th><th>max</th><th>range</th><th>previous range</th><th>change</th></tr>";
  for (const std::string& j : anatomicalKeys(m["rom_deg"])) {
    const nlohmann::json& r = m["rom_deg"][j];
    const double range = r[1].get<double>() - r[0].get<double>();
    h << "<tr><td>" << esc(j) << "</td><td>" << fmt(r[0].get<double>(), 1) << "</td><td>" << fmt(r[1].get<double>(), 1)
      << "</td><td>" << fmt(range, 1) << "</td>";
    if (prom.is_object() && prom.contains(j)) {
      const double pr = prom[j][1].get<double>() - prom[j][0].get<double>();
      // A larger active range is the better one; a change under 0.5° is within the ROM's own noise (therapy.md).
      const double d = range - pr;
      const char* word = std::fabs(d) < 0.5 ? "same" : d > 0 ? "better" : "worse";
      h << "<td>" << fmt(pr, 1) << "</td><td class='" << word << "'>" << (d >= 0 ? "+" : "−") << fmt(std::fabs(d), 1)
        << "° " << (std::fabs(d) < 0.5 ? "(no change)" : d > 0 ? "▲ better" : "▼ worse") << "</td>";
    } else {
      h << "<td>–</td><td>–</td>";
    }
    h << "</tr>";
  }
  h << "</table>";
  h << instrumentedHtml(m, rep, unit);
  // Transparency.
  h << "<h2>Transparency</h2>";
  if (m["transparency"].empty()) {
    h << "<p>No assessment (transparent) phase in this session.</p>";
  } else {
    h << "<p class='note'>Interaction " << (unit == "N" ? "force" : "torque")
      << " while the device followed the hand (assessment); the glove paper measured ≈ 0.1 N peak (000 §4.3), "
         "the exoskeleton paper 0.0029 / 0.0092 N·m RMS at MCP / PIP (001 §8.7).</p>";
    h << "<table><tr><th>channel</th><th>RMS (" << esc(unit) << ")</th><th>peak (" << esc(unit) << ")</th></tr>";
    for (const std::string& c : anatomicalKeys(m["transparency"])) {
      const nlohmann::json& v = m["transparency"][c];
      h << "<tr><td>" << esc(c) << "</td><td>" << fmt(v["interaction_rms"].get<double>(), 3) << "</td><td>"
        << fmt(v["interaction_peak"].get<double>(), 3) << "</td></tr>";
    }
    h << "</table>";
  }
  if (m.contains("transparency_r") && !m["transparency_r"].empty()) {
    h << "<p class='note'>Kinematic transparency (001 Table 2, 000 Table 4): Pearson r between each joint's "
         "trajectory with the device (assessment) and a device-free recording of the same motion ("
      << esc(reference_path) << "). 001 Table 2, full flexion–extension (iii): MCP 0.894, PIP 0.985, DIP 0.989.</p>"
      << "<table><tr><th>joint</th><th>Pearson r</th><th>RMS difference (deg)</th><th>samples</th></tr>";
    for (const std::string& j : anatomicalKeys(m["transparency_r"])) {
      const nlohmann::json& v = m["transparency_r"][j];
      h << "<tr><td>" << esc(j) << "</td><td>"
        << (v["pearson_r"].is_number() ? fmt(v["pearson_r"].get<double>(), 4) : "–") << "</td><td>"
        << fmt(v["rms_difference_deg"].get<double>(), 2) << "</td><td>" << v["samples"].get<std::size_t>() << "</td></tr>";
    }
    h << "</table>";
  } else if (!m["transparency"].empty()) {
    h << "<p class='note'>The Pearson r of 001 Table 2 / 000 Table 4 compares joint trajectories with and without "
         "the device; give a device-free recording of the same motion (phalanx record report --reference) to "
         "compute it.</p>";
  }
  // Tracking.
  h << "<h2>Tracking (assistance, playback)</h2>";
  if (m["tracking"].empty()) {
    h << "<p>No assistance or playback in this session.</p>";
  } else {
    h << "<p class='note'>Target vs measured finger flexion (sum of the finger's joints).</p><table><tr><th>channel</th>"
         "<th>RMS error (deg)</th><th>Pearson r</th><th>time (s)</th></tr>";
    for (const std::string& c : anatomicalKeys(m["tracking"])) {
      const nlohmann::json& v = m["tracking"][c];
      h << "<tr><td>" << esc(c) << "</td><td>" << fmt(v["rms_error_deg"].get<double>(), 1) << "</td><td>"
        << (v["pearson_r"].is_number() ? fmt(v["pearson_r"].get<double>(), 3) : "–") << "</td><td>"
        << fmt(v["seconds"].get<double>(), 1) << "</td></tr>";
    }
    h << "</table>";
  }
  // Traces.
  h << "<h2>Traces</h2>";
  std::vector<std::pair<std::string, const std::vector<double>*>> forces, cmds, qs;
  std::vector<std::vector<double>> q_deg(dev.channelCount()), tg_deg(dev.channelCount());
  for (std::size_t c = 0; c < dev.channelCount(); ++c) {
    for (double v : s.q[c]) q_deg[c].push_back(v * kDeg);
    for (double v : s.target[c]) tg_deg[c].push_back(v * kDeg);
  }
  for (std::size_t c = 0; c < dev.channelCount(); ++c) {
    forces.emplace_back(dev.channelName(c), &s.effort[c]);
    cmds.emplace_back(dev.channelName(c), &s.effort_cmd[c]);
    qs.emplace_back(dev.channelName(c), &q_deg[c]);
  }
  h << svgPlot(std::string("Measured ") + (unit == "N" ? "fingertip force" : "joint torque") + " (+ resists flexion)",
               unit, s.t, forces);
  h << svgPlot("Commanded effort", unit, s.t, cmds);
  h << svgPlot("Finger flexion (sum of joints)", "deg", s.t, qs);
  if (!m["tracking"].empty()) {
    for (std::size_t c = 0; c < dev.channelCount(); ++c) {
      if (!m["tracking"].contains(dev.channelName(c))) continue;
      h << svgPlot("Tracking: " + dev.channelName(c), "deg", s.t,
                   {{"target", &tg_deg[c]}, {"measured", &q_deg[c]}});
      break;  // one example channel; the table has them all
    }
  }
  // Faults and events.
  h << "<h2>Faults and events</h2><p>Faults seen: <b>" << esc(m["faults_seen"].get<std::string>()) << "</b>; effort "
    << "limits engaged " << m["limit_onsets"].get<long>() << " time(s)"
    << (m["record_cycles_dropped"].get<long>() > 0
            ? "; <span class='warn'>" + std::to_string(m["record_cycles_dropped"].get<long>()) + " cycles not recorded</span>"
            : "")
    << ".</p>";
  if (!m["faults"].empty()) {
    h << "<table><tr><th>time (s)</th><th>faults</th></tr>";
    for (const auto& f : m["faults"]) {
      h << "<tr><td>" << fmt(f["t_s"].get<double>(), 3) << "</td><td>" << esc(f["faults"].get<std::string>()) << "</td></tr>";
    }
    h << "</table>";
  }
  uint16_t seen_bits = 0;
  for (const uint16_t f : s.faults) seen_bits |= f;
  if (seen_bits != 0) {
    h << "<h3>What the faults mean</h3><table><tr><th>fault</th><th>what happened</th><th>was the patient safe</th>"
         "<th>what to do</th></tr>";
    for (const auto& g : faultGuidance(seen_bits)) {
      h << "<tr><td>" << esc(g.fault) << "</td><td class='text'>" << esc(g.what) << "</td><td class='text'>"
        << esc(g.safe) << "</td><td class='text'>" << esc(g.action) << "</td></tr>";
    }
    h << "</table>";
  }
  if (!m["therapist_requests"].empty()) {
    h << "<h3>Therapist requests</h3><table><tr><th>time (s)</th><th>request</th><th>details</th></tr>";
    for (const auto& e : m["therapist_requests"]) {
      const auto [what, details] = describeRequest(e, unit);
      h << "<tr><td>" << fmt(e.value("t_s", 0.0), 1) << "</td><td class='text'>" << esc(what)
        << "</td><td class='text'>" << esc(details) << "</td></tr>";
    }
    h << "</table>";
  }
  h << "<script type='application/json' id='metrics'>" << esc(m.dump()) << "</script>";
  h << "<p class='note'>Generated by phalanx from the session record. Peak measured effort per channel: ";
  for (const std::string& c : anatomicalKeys(m["effort"])) h << esc(c) << " " << fmt(m["effort"][c]["peak_measured"].get<double>(), 2) << " ";
  h << esc(unit) << ".</p></body></html>\n";
  // A temporary file renamed into place: a failed write never leaves a half report over an existing one.
  record::AtomicOutputFile out;
  if (std::string err = out.open(html_path); !err.empty()) return err;
  out.write(h.str());
  return out.commit();
}

std::string writeRepeatability(const std::vector<std::string>& records, const std::string& out_path,
                               nlohmann::json& result) {
  std::vector<std::string> patients;
  std::vector<std::vector<nlohmann::json>> sessions;
  for (const std::string& path : records) {
    if (std::string err = record::refuseSameFile(path, out_path); !err.empty()) return err;
    record::SessionRecord rec;
    if (std::string err = record::readRecord(path, rec); !err.empty()) return err;
    const std::string patient = recordPatient(rec);
    if (patient.empty()) return path + ": the record names no patient (a session without a profile)";
    nlohmann::json m = sessionMetrics(rec);
    if (m.contains("error")) return path + ": " + m["error"].get<std::string>();
    const auto it = std::find(patients.begin(), patients.end(), patient);
    if (it == patients.end()) patients.push_back(patient), sessions.emplace_back();
    sessions[static_cast<std::size_t>(std::find(patients.begin(), patients.end(), patient) - patients.begin())]
        .push_back(std::move(m));
  }
  for (std::size_t p = 0; p < patients.size(); ++p) {
    if (sessions[p].size() != sessions[0].size()) {
      return "patient '" + patients[p] + "' has " + std::to_string(sessions[p].size()) + " records, '" + patients[0] +
             "' has " + std::to_string(sessions[0].size()) + ": every patient needs the same number of sessions";
    }
  }
  std::string error;
  result = repeatabilityOf(sessions, std::to_string(patients.size()) + " patients x " +
                                         std::to_string(sessions.empty() ? 0 : sessions[0].size()) + " sessions",
                           error);
  if (!error.empty()) return error;
  result["patients"] = patients;
  std::ofstream f(out_path);
  f << result.dump(1) << "\n";
  f.close();
  return f ? "" : out_path + ": cannot write";
}

}  // namespace phalanx::host::therapy
