#pragma once
/// The instrumented assessments' figures, computed from a session's per-cycle series (the report and the tests
/// use the same functions). docs/therapy.md "Instrumented assessments" gives the method and its tolerances.
///  - Modified Tardieu (exercise `tardieu`): each imposed stretch is a run of decreasing target; the slowest is
///    the passive reference (its effort against angle, 1° bins). Every sample of the other stretches (5° after
///    the start to 3° before the end) gives its excess effort over the reference at the same angle and its
///    stretch velocity v (least-squares slope over ±10 ms); one model is fitted to all of them by least squares:
///        excess = a + b·v + G·(v − v_th)⁺ · [q < φ_c]
///    (a, b: offset and viscous part; G: reflex gain, v_th: threshold velocity, φ_c: catch angle; grid search
///    over φ_c and v_th, linear in the rest). A reflex is reported only when G·(v_max − v_th) exceeds 3× the fit's
///    RMS residual. Per stretch: its mean velocity past the catch, its catch (the first angle past φ_c with
///    v > v_th — Tardieu's R1 at that velocity; none if never), its mean reflex excess, its mean effort.
///  - Passive ROM (exercise `passive-rom`): per joint, the flexion the relaxed finger settles at under the
///    extending and the flexing test effort (mean of the last quarter of each).
///  - Maximal voluntary force (exercise `max-force`): per channel, the peak of the 5 Hz low-passed measured
///    effort while the device holds the pose, less the relaxed baseline (the mean of the phase's first 0.3 s).
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace phalanx::host::therapy {

struct StretchFigures {
  double nominal_rad_s = 0.0;     ///< the imposed (target) stretch velocity
  double velocity_rad_s = 0.0;    ///< mean measured stretch (extension) velocity after the catch (or over the ramp)
  double resistance = 0.0;        ///< mean measured effort over the ramp (+ resists flexion)
  double catch_rad = 0.0;         ///< flexion at the catch; NaN: no catch
  double reflex = 0.0;            ///< mean excess effort after the catch over the early-ramp excess; 0 without
};

struct TardieuFigures {
  std::vector<StretchFigures> stretches;  ///< in the order performed (slowest first by default)
  double catch_rad = 0.0;                 ///< at the fastest stretch with a catch (Tardieu R1); NaN: none
  double threshold_rad_s = 0.0;           ///< reflex threshold velocity (NaN: fewer than 2 stretches with a catch)
  double gain_per_rad_s = 0.0;            ///< reflex effort per rad/s above the threshold (NaN as above)
  double residual = 0.0;                  ///< RMS residual of the model fit (effort)
};

/// t, q (the stretched channel's coordinate, rad), effort (measured), target (rad), in (cycles of the tardieu
/// exercise). All the same length. "" or an error (no stretches, too few, lengths differ).
std::string analyseTardieu(const std::vector<double>& t, const std::vector<double>& q,
                           const std::vector<double>& effort, const std::vector<double>& target,
                           const std::vector<char>& in, TardieuFigures& out);

struct PassiveRomFigures {
  double extension_rad = 0.0;  ///< flexion reached under the extending effort (NaN: no such phase)
  double flexion_rad = 0.0;    ///< flexion reached under the flexing effort
};
/// One joint: its flexion, the commanded effort of its channel, and the cycles of the passive-rom exercise.
PassiveRomFigures analysePassiveRom(const std::vector<double>& flexion, const std::vector<double>& effort_cmd,
                                    const std::vector<char>& in);

/// One channel: the peak of the 5 Hz low-passed effort over the cycles in `in` less the mean of their first
/// 0.3 s (NaN: none).
double analyseMaxForce(const std::vector<double>& t, const std::vector<double>& effort, const std::vector<char>& in);

/// Every instrumented-assessment figure of a session's metrics (sessionMetrics()["instrumented"]) as
/// (name, value) pairs in a fixed order: tardieu.catch_deg, tardieu.threshold_deg_s, tardieu.gain_per_rad_s,
/// tardieu.reflex_at_<v>_deg_s (per stretch velocity), passive_rom.<joint>.{extension,flexion}_deg,
/// max_force.<channel>, rom.<joint>.{min,max}_deg (active ROM), joints and channels in anatomical order.
/// Non-finite figures are left out.
std::vector<std::pair<std::string, double>> assessmentFigures(const nlohmann::json& metrics);

/// The unit of an assessmentFigures() figure for a device whose effort unit is `effort_unit` ("N", "N·m"):
/// "°" for angles, "°/s" for velocities, effort_unit·s/rad for the reflex gain, else effort_unit.
std::string figureUnit(const std::string& name, const std::string& effort_unit);

/// The repeatability of every assessment figure from sessions[patient][session] = that session's metrics
/// (sessionMetrics()): for each figure present in every session, ICC(2,1), SEM, MDC95 (repeatability.h).
/// Every patient must have the same number (≥ 2) of sessions, and there must be ≥ 2 patients. Returns the
/// repeatability file's JSON (loadRepeatability's format, with `source`) or sets error.
nlohmann::json repeatabilityOf(const std::vector<std::vector<nlohmann::json>>& sessions, const std::string& source,
                               std::string& error);

/// A repeatability file (JSON, docs/therapy.md "Repeatability"): {"version": 1, "figures": {name: {"icc",
/// "sem", "mdc95", "subjects", "sessions"}}}. "" or "<path>: <problem>".
std::string loadRepeatability(const std::string& path, nlohmann::json& out);

}  // namespace phalanx::host::therapy
