#include "phalanx/sim/sea_plant.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace phalanx::sim {

namespace {

namespace board = ::phalanx::sea::board;

constexpr double kPi = 3.14159265358979323846;
double asDouble(float x) { return static_cast<double>(x); }
double sign(double x) { return x > 0.0 ? 1.0 : (x < 0.0 ? -1.0 : 0.0); }

bool finitePositive(double x) { return std::isfinite(x) && x > 0.0; }
bool finiteNonNegative(double x) { return std::isfinite(x) && x >= 0.0; }
void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(what);
}

void validate(const SeaPlantConfig& c) {
  const SeaPlantParams& p = c.params;
  require(c.variant == SeaVariant::kRig, "SeaPlantConfig: unknown variant");
  for (const SeaChannelParams& s : p.channel) {
    require(finitePositive(s.spring_stiffness_N_per_m), "SeaChannelParams: spring_stiffness_N_per_m must be > 0");
    require(finitePositive(s.joint_pulley_radius_m), "SeaChannelParams: joint_pulley_radius_m must be > 0");
    require(finitePositive(s.motor_pulley_radius_m), "SeaChannelParams: motor_pulley_radius_m must be > 0");
    require(finiteNonNegative(s.pretension_N), "SeaChannelParams: pretension_N must be >= 0");
    require(finiteNonNegative(s.backlash_base_m), "SeaChannelParams: backlash_base_m must be >= 0");
    require(finiteNonNegative(s.backlash_per_Nm_m), "SeaChannelParams: backlash_per_Nm_m must be >= 0");
    require(finiteNonNegative(s.sheath_friction) && s.sheath_friction < 1.0,
            "SeaChannelParams: sheath_friction must be in [0, 1)");
    require(finitePositive(s.clamp_stiffness_Nm_per_rad), "SeaChannelParams: clamp_stiffness_Nm_per_rad must be > 0");
  }
  const double positive[] = {p.supply_V, p.motor_resistance_Ohm, p.bridge_current_limit_A, p.motor_inductance_H,
                             p.torque_constant_Nm_per_A, p.rotor_inertia_kg_m2, p.gear_ratio, p.gear_efficiency,
                             p.max_substep_s};
  for (double v : positive) require(finitePositive(v), "SeaPlantParams: a value that must be > 0 is not");
  require(p.gear_efficiency <= 1.0, "SeaPlantParams: gear_efficiency must be <= 1");
  const double non_negative[] = {p.bridge_on_resistance_Ohm, p.no_load_current_A, p.output_inertia_kg_m2,
                                 p.joint_noise_counts, p.current_noise_counts, p.load_cell_noise_counts};
  for (double v : non_negative) require(finiteNonNegative(v), "SeaPlantParams: a value that must be >= 0 is not");
}

int32_t toCounts(double counts) {
  const double r = std::round(counts);
  return static_cast<int32_t>(std::clamp(r, 0.0, static_cast<double>(board::kAdcMaxCounts)));
}

}  // namespace

SeaPlant::SeaPlant(const SeaPlantConfig& config) : config_(config), rng_(config.seed) {
  validate(config_);
  const SeaPlantParams& p = config_.params;
  for (size_t i = 0; i < ch_.size(); ++i) {
    Channel& c = ch_[i];
    c.p = p.channel[i];
    c.inertia = p.rotor_inertia_kg_m2 * p.gear_ratio * p.gear_ratio + p.output_inertia_kg_m2;
    solveJoint(c);
  }
}

int SeaPlant::idx(int sea) {
  if (sea < 0 || sea > 1) throw std::out_of_range("SeaPlant: SEA index must be 0 (MCP) or 1 (PIP)");
  return sea;
}

const SeaTruth& SeaPlant::truth(int sea) const { return ch_[static_cast<size_t>(idx(sea))].truth; }

double SeaPlant::idealSeaTorque_Nm(int sea) const {
  const Channel& c = ch_[static_cast<size_t>(idx(sea))];
  const double rj = c.p.joint_pulley_radius_m;
  // eq 2 with θ_j0 = 0 (the plant's joint zero is the unloaded clamp pose).
  return 2.0 * c.p.spring_stiffness_N_per_m * (c.p.motor_pulley_radius_m * c.theta_m - rj * c.theta_j) * rj;
}

// Rig: massless joint pulley held by the clamp, k_clamp θ_j = τ_j(θ_j). τ_j is piecewise linear in θ_j (both
// cables taut, or one slack), so each region is solved in closed form and the consistent one is kept.
void SeaPlant::solveJoint(Channel& c) const {
  const double k = c.p.spring_stiffness_N_per_m;
  const double r = c.p.joint_pulley_radius_m;
  const double a = c.p.clamp_stiffness_Nm_per_rad;
  const double t0 = c.p.pretension_N;
  const double x = c.x_e;
  double theta = 2.0 * k * r * x / (a + 2.0 * k * r * r);  // both taut: τ_j = 2k d r_j (eq 2)
  double d = x - r * theta;
  if (k * d > t0) {
    theta = r * (t0 + k * x) / (a + k * r * r);  // cable 1 slack: τ_j = (T_0 + k d) r_j
  } else if (k * d < -t0) {
    theta = r * (k * x - t0) / (a + k * r * r);  // cable 2 slack: τ_j = −(T_0 − k d) r_j
  }
  d = x - r * theta;
  const double t1 = std::max(0.0, t0 - k * d);
  const double t2 = std::max(0.0, t0 + k * d);
  c.theta_j = theta;
  SeaTruth& t = c.truth;
  t.joint_angle_rad = theta;
  t.spring_deflection_m = d;
  t.tension1_N = t1;
  t.tension2_N = t2;
  t.joint_torque_Nm = (t2 - t1) * r;
  t.load_cell_torque_Nm = a * theta;
}

void SeaPlant::substep(Channel& c, double duty, bool bridge_on, double h) {
  const SeaPlantParams& p = config_.params;
  const double n = p.gear_ratio;
  const double kt = p.torque_constant_Nm_per_A;
  const double r_total = p.motor_resistance_Ohm + p.bridge_on_resistance_Ohm;

  // Armature: L di/dt = V − R i − k_e N ω, exact over the substep for a constant V and ω. The bridge regulates
  // the current cycle by cycle at its limit. Disabled bridge: high impedance, the current collapses through the
  // body diodes within microseconds (back-EMF stays below the supply at every reachable speed), so i = 0.
  double voltage = 0.0;
  if (bridge_on) {
    voltage = std::clamp(duty, -1.0, 1.0) * p.supply_V;
    const double i_ss = (voltage - kt * n * c.omega_m) / r_total;
    c.current = i_ss + (c.current - i_ss) * std::exp(-h * r_total / p.motor_inductance_H);
    c.current = std::clamp(c.current, -p.bridge_current_limit_A, p.bridge_current_limit_A);
  } else {
    c.current = 0.0;
  }

  // Bowden cable play: the spring side follows the motor side only once the motor has taken up the play.
  const double x_m = c.p.motor_pulley_radius_m * c.theta_m;
  const double half = 0.5 * (c.p.backlash_base_m + c.p.backlash_per_Nm_m * std::fabs(c.truth.joint_torque_Nm));
  c.x_e = std::clamp(c.x_e, x_m - half, x_m + half);
  solveJoint(c);

  const double sheath_N = c.p.sheath_friction * (c.truth.tension1_N + c.truth.tension2_N);
  const double s = half > 0.0 ? (x_m - c.x_e) / half : 0.0;
  const double cable_load = c.p.motor_pulley_radius_m * ((c.truth.tension2_N - c.truth.tension1_N) + sheath_N * s);

  // Motor + gearhead at the pulley: Coulomb friction (no-load friction + the gear loss on the transmitted motor
  // torque), with stiction, integrated at the velocity level so that a stuck drive stays exactly stuck.
  const double tau_motor = n * kt * c.current;
  double coulomb = n * kt * p.no_load_current_A + (1.0 - p.gear_efficiency) * std::fabs(tau_motor);
  if (half <= 0.0) coulomb += c.p.motor_pulley_radius_m * sheath_N;  // rigid cable: sheath friction at the motor
  const double v_free = c.omega_m + h * (tau_motor - cable_load) / c.inertia;
  const double dv_friction = h * coulomb / c.inertia;
  c.omega_m = std::fabs(v_free) <= dv_friction ? 0.0 : v_free - sign(v_free) * dv_friction;
  c.theta_m += h * c.omega_m;

  SeaTruth& t = c.truth;
  t.motor_angle_rad = c.theta_m;
  t.motor_speed_rad_s = c.omega_m;
  t.motor_current_A = c.current;
  t.motor_voltage_V = voltage;
  t.cable_motor_m = x_m;
  t.cable_spring_m = c.x_e;
  t.backlash_m = 2.0 * half;
  t.cable_load_torque_Nm = cable_load;
  t.bridge_on = bridge_on;
}

void SeaPlant::step(double dt_s, SimIo& io) {
  if (!(std::isfinite(dt_s) && dt_s > 0.0 && dt_s <= 1.0)) {
    throw std::invalid_argument("SeaPlant::step: dt_s must be finite and in (0, 1]");
  }
  const bool bridge_on = io.pwm_enabled && io.drive_enable && !io.estop_pressed;
  const auto n = static_cast<long>(std::ceil(dt_s / config_.params.max_substep_s - 1e-9));
  const double h = dt_s / static_cast<double>(n);
  for (size_t i = 0; i < ch_.size(); ++i) {
    const double duty = asDouble(io.pwm_duty[i]);
    for (long k = 0; k < n; ++k) substep(ch_[i], std::isfinite(duty) ? duty : 0.0, bridge_on, h);
  }
  time_s_ += dt_s;
  sample(io);
}

double SeaPlant::gaussian() {
  const auto u = [this] { return (static_cast<double>(rng_()) + 0.5) * (1.0 / 4294967296.0); };
  const double u1 = u();
  const double u2 = u();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
}

void SeaPlant::sample(SimIo& io) {
  const SeaPlantParams& p = config_.params;
  const double noise = config_.noise ? 1.0 : 0.0;
  const double mid = static_cast<double>(board::kAdcMidCounts);
  // Joint sensors: 0 and 1 are the SEA joints; on the rig the other three sit on an unmoving fixture.
  for (int s = 0; s < board::kJointSensorCount; ++s) {
    const double angle = s < 2 ? ch_[static_cast<size_t>(s)].theta_j : 0.0;
    const double counts = mid + (angle - asDouble(board::kJointCentre_rad[static_cast<size_t>(s)])) *
                                    asDouble(board::kJointCountsPerRad);
    io.adc[static_cast<size_t>(board::kAdcFirstJoint + s)] = toCounts(counts + noise * p.joint_noise_counts * gaussian());
  }
  for (size_t i = 0; i < ch_.size(); ++i) {
    const Channel& c = ch_[i];
    // Encoder at the motor shaft; quantised to whole counts (floor, as a quadrature counter does).
    const double motor_counts = c.theta_m / asDouble(board::kMotorRadPerCount);
    io.encoder[i] = static_cast<int32_t>(std::floor(motor_counts));
    const double current_counts = mid + c.current * asDouble(board::kCurrentCountsPerAmp);
    io.adc[static_cast<size_t>(board::kAdcFirstCurrent) + i] =
        toCounts(current_counts + noise * p.current_noise_counts * gaussian());
    const double lc_counts = mid + c.truth.load_cell_torque_Nm * asDouble(board::kLoadCellCountsPerNm);
    io.adc[static_cast<size_t>(board::kAdcFirstLoadCell) + i] =
        toCounts(lc_counts + noise * p.load_cell_noise_counts * gaussian());
  }
}

}  // namespace phalanx::sim
