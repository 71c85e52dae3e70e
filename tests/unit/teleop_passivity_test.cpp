// The delayed position-force teleoperation channel with and without time-domain passivity control
// (host/include/phalanx/host/teleop/passivity.h), closed in lockstep: an operator's hand (arm spring-damper towards a
// target that presses 2 cm beyond the remote wall, grip spring-damper to the device, as the pen plant's hand) on a
// 0.1 kg master device, a network that delays every sample by a whole number of cycles and loses some (seeded),
// and the slave arm against its 5 kN/m wall. The real-time version over DDS with tc netem is
// tests/dds/teleop_netns_test.sh.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <random>

#include "phalanx/host/teleop/passivity.h"

namespace {

using namespace phalanx::teleop;

struct Result {
  double hold_peak_to_peak_m = 0;  // master position, last 2 s of the press
  int contact_changes = 0;         // in the last 2 s of the press
  double hold_force_N = 0;         // mean displayed force magnitude, last 2 s
  double channel_net_out_J = 0;    // E_out − E_in over both ports at the end: ≤ 0 for a passive channel
  double worst_bound_excess_J = 0;  // max over cycles of E_out at a port − the other's E_in that had arrived
  double hold_velocity_rms_m_s = 0; // master, last 2 s of the press: an oscillation shows here, a slow creep not
  double earlier_velocity_rms_m_s = 0;  // the 2 s before: a growing oscillation is larger in the last 2 s
  double max_force_N = 0;
};

/// A network direction: each sample arrives delay_cycles later, or never (loss).
class Link {
 public:
  Link(int delay_cycles, double loss, uint32_t seed) : delay_(delay_cycles), loss_(loss), rng_(seed) {}
  void send(const Sample& s, int now) {
    if (std::uniform_real_distribution<double>(0, 1)(rng_) < loss_) return;
    q_.push_back({now + delay_, s});
  }
  /// The newest sample due by now; false if none arrived yet.
  bool receive(int now, Sample& out) {
    bool got = false;
    while (!q_.empty() && q_.front().first <= now) {
      newest_ = q_.front().second;
      q_.pop_front();
      got = have_ = true;
    }
    out = newest_;
    return have_ || got;
  }

 private:
  int delay_;
  double loss_;
  std::mt19937 rng_;
  std::deque<std::pair<int, Sample>> q_;
  Sample newest_;
  bool have_ = false;
};

Result run(Scheme scheme, int delay_ms, double loss, double wall_N_per_m = 5000.0, uint32_t seed = 7) {
  const double dt = 1e-3;
  MasterPort::Config mc;
  mc.scheme = scheme;
  SlavePort::Config sc;
  sc.scheme = scheme;
  MasterPort master(mc);
  SlavePort slave(sc);
  SlaveArm arm;
  arm.cfg.wall_stiffness_N_per_m = wall_N_per_m;
  Link to_slave(delay_ms, loss, seed), to_master(delay_ms, loss, seed + 1);
  // Master device (x: towards the wall) and the operator's hand.
  const double m_dev = 0.1, m_hand = 0.25, k_grip = 2000, b_grip = 8, k_arm = 200, b_arm = 5;
  Vec3 xd{}, vd{}, xh{}, vh{};
  Sample from_slave, from_master;
  Result r;
  std::vector<double> hold_x;
  bool was_contact = false;
  double force_sum = 0, v2_sum = 0, v2_early = 0;
  int force_n = 0;
  const int cycles = 8000;
  for (int n = 0; n < cycles; ++n) {
    const double t = n * dt;
    // The operator presses 2 cm beyond the wall (ramp over 1 s from t = 0.5 s), then holds.
    const double target = arm.cfg.wall_x_m + 0.02 * std::clamp((t - 0.5) / 1.0, 0.0, 1.0);
    const bool has_slave = to_master.receive(n, from_slave);
    const Vec3 F = master.step(xd, from_slave, has_slave, dt);
    r.max_force_N = std::max(r.max_force_N, std::fabs(F[0]));
    if (has_slave) r.worst_bound_excess_J = std::max(r.worst_bound_excess_J, master.energy().out_J - from_slave.energy_in_J);
    Sample ms;
    ms.seq = static_cast<uint32_t>(n + 1);
    ms.position_m = xd;
    ms.velocity_m_s = vd;
    ms.energy_in_J = master.energy().in_J;
    to_slave.send(ms, n);
    const bool has_master = to_slave.receive(n, from_master);
    const Vec3 Fc = slave.step(arm.x_m, arm.v_m_s, from_master, has_master, dt);
    if (has_master) r.worst_bound_excess_J = std::max(r.worst_bound_excess_J, slave.energy().out_J - from_master.energy_in_J);
    arm.step(Fc, dt);
    Sample ss;
    ss.position_m = arm.x_m;
    ss.force_N = Fc;
    ss.energy_in_J = slave.energy().in_J;
    to_master.send(ss, n);
    // Operator and device, semi-implicit Euler in 10 substeps, x only (the other axes carry no force here).
    for (int k = 0; k < 10; ++k) {
      const double h = dt / 10;
      const double grip = k_grip * (xh[0] - xd[0]) + b_grip * (vh[0] - vd[0]);
      const double arm_f = k_arm * (target - xh[0]) - b_arm * vh[0];
      vh[0] += (arm_f - grip) / m_hand * h;
      vd[0] += (grip + F[0]) / m_dev * h;
      xh[0] += vh[0] * h;
      xd[0] += vd[0] * h;
    }
    if (t >= 4.0 && t < 6.0) v2_early += vd[0] * vd[0];
    if (t >= 6.0) {
      hold_x.push_back(xd[0]);
      v2_sum += vd[0] * vd[0];
      const bool c = arm.inContact();
      if (n > 6000 && c != was_contact) ++r.contact_changes;
      was_contact = c;
      force_sum += std::fabs(F[0]);
      ++force_n;
    }
  }
  const auto [lo, hi] = std::minmax_element(hold_x.begin(), hold_x.end());
  r.hold_peak_to_peak_m = *hi - *lo;
  r.hold_force_N = force_sum / force_n;
  r.hold_velocity_rms_m_s = std::sqrt(v2_sum / force_n);
  r.earlier_velocity_rms_m_s = std::sqrt(v2_early / force_n);
  r.channel_net_out_J = master.energy().out_J + slave.energy().out_J - master.energy().in_J - slave.energy().in_J;
  return r;
}

TEST(PortEnergy, SplitsPowerIntoInAndOut) {
  PortEnergy e;
  e.add(2.0, 0.5);
  e.add(-1.0, 0.5);
  e.add(0.0, 1.0);
  EXPECT_DOUBLE_EQ(e.in_J, 1.0);
  EXPECT_DOUBLE_EQ(e.out_J, 0.5);
}

TEST(Scheme, ParsesItsNames) {
  Scheme s = Scheme::kPlain;
  EXPECT_TRUE(parseScheme("passive", s));
  EXPECT_EQ(s, Scheme::kPassive);
  EXPECT_TRUE(parseScheme("plain", s));
  EXPECT_EQ(s, Scheme::kPlain);
  EXPECT_FALSE(parseScheme("wave", s));
  EXPECT_STREQ(schemeName(Scheme::kPassive), "passive");
}

TEST(Teleop, WithoutDelayBothSchemesHoldTheWall) {
  for (Scheme s : {Scheme::kPlain, Scheme::kPassive}) {
    const Result r = run(s, 0, 0.0);
    SCOPED_TRACE(schemeName(s));
    EXPECT_LT(r.hold_peak_to_peak_m, 0.5e-3);
    EXPECT_EQ(r.contact_changes, 0);
    // The operator's arm presses 2 cm beyond the wall with 200 N/m: about 4 N less what its spring has relaxed
    // into the coupling and the wall (1 kN/m in series with 5 kN/m).
    EXPECT_GT(r.hold_force_N, 2.0);
    EXPECT_LT(r.hold_force_N, 4.0);
  }
}

TEST(Teleop, PlainSchemeGoesUnstableOnTheWallUnderDelay) {
  for (int delay : {10, 50, 100}) {
    const Result r = run(Scheme::kPlain, delay, 0.0);
    SCOPED_TRACE("delay " + std::to_string(delay) + " ms");
    EXPECT_GT(r.hold_peak_to_peak_m, 5e-3) << "the plain delayed scheme should bounce on the 5 kN/m wall";
    EXPECT_GT(r.contact_changes, 2);
    EXPECT_GT(r.channel_net_out_J, 0.1) << "the delayed plain channel generates energy";
  }
}

TEST(Teleop, PassiveSchemeHoldsTheWallAtEveryDelayAndLoss) {
  for (int delay : {0, 10, 50, 100}) {
    for (double loss : {0.0, 0.05}) {
      const Result r = run(Scheme::kPassive, delay, loss);
      SCOPED_TRACE("delay " + std::to_string(delay) + " ms, loss " + std::to_string(loss));
      // Passive up to the damper's bound (MasterPort::Config): a few mJ over the whole run, not growing.
      EXPECT_LT(r.worst_bound_excess_J, 0.01);
      EXPECT_LT(r.channel_net_out_J, 0.01);
      EXPECT_LT(r.hold_peak_to_peak_m, 1e-3);
      EXPECT_LE(r.hold_velocity_rms_m_s, r.earlier_velocity_rms_m_s + 1e-3) << "a growing oscillation";
      EXPECT_EQ(r.contact_changes, 0);
      EXPECT_GT(r.hold_force_N, 0.5) << "the operator still feels the wall";
    }
  }
}

}  // namespace

namespace {
// The table of docs/teleop.md (printed, not gated beyond the tests above).
TEST(Teleop, PrintsTheLockstepTable) {
  std::printf("scheme  delay_ms loss  p2p_mm v_rms_4-6s v_rms_6-8s contact_changes hold_force_N max_force_N net_out_J excess_J\n");
  for (Scheme s : {Scheme::kPlain, Scheme::kPassive})
    for (int delay : {0, 10, 50, 100})
      for (double loss : {0.0, 0.05}) {
        const Result r = run(s, delay, loss);
        std::printf("%-7s %8d %4.2f %7.2f %10.2f %10.2f %15d %12.2f %11.2f %9.4f %8.2g\n", schemeName(s), delay, loss,
                    r.hold_peak_to_peak_m * 1e3, r.earlier_velocity_rms_m_s * 1e3, r.hold_velocity_rms_m_s * 1e3, r.contact_changes, r.hold_force_N,
                    r.max_force_N, r.channel_net_out_J, r.worst_bound_excess_J);
      }
}
}  // namespace

namespace {
bool holds(const Result& r) {
  return r.contact_changes == 0 && r.hold_peak_to_peak_m < 1e-3 && r.hold_velocity_rms_m_s <= r.earlier_velocity_rms_m_s + 1e-3;
}

// The largest wall stiffness each scheme holds, per delay (docs/teleop.md): printed, and the passive scheme must
// hold at least what the plain one holds at every delay.
TEST(Teleop, LargestStableWallStiffness) {
  const double ks[] = {100, 200, 500, 1000, 2000, 5000, 10000, 20000, 50000};
  std::printf("largest stable wall stiffness, N/m (of 100 ... 50000; 0: none)\n delay_ms  plain  passive\n");
  for (int delay : {0, 10, 50, 100}) {
    double best[2] = {0, 0};
    for (Scheme s : {Scheme::kPlain, Scheme::kPassive})
      for (double k : ks)
        if (holds(run(s, delay, 0.0, k))) best[static_cast<int>(s)] = k;
    std::printf("%9d %6.0f %8.0f\n", delay, best[0], best[1]);
    EXPECT_GE(best[1], best[0]) << "delay " << delay;
    EXPECT_EQ(best[1], 50000.0) << "the passive scheme should hold the stiffest wall tried at " << delay << " ms";
  }
}
}  // namespace
