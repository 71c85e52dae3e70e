#pragma once
/// Bilateral teleoperation over a delayed, lossy network, position forward and force back (docs/teleop.md), made
/// passive by time-domain passivity control on the time-delay power network (TDPN):
///   J. Artigas, J.-H. Ryu, C. Preusche, G. Hirzinger, "Network representation and passivity of delayed
///   teleoperation systems", IEEE/RSJ IROS 2011; the passivity observer/controller pair of B. Hannaford,
///   J.-H. Ryu, "Time-domain passivity control of haptic interfaces", IEEE Trans. Robotics and Automation 18(1), 2002.
///
/// The channel between the master (the operator's device) and the slave (the remote arm) is a two-port. Power
/// entering it at a port is split into what flows in (E_in, counted when positive) and what flows out (E_out); each
/// side sends its cumulative E_in with every sample. The channel is passive when the energy leaving at each port
/// never exceeds the energy that entered at the other port and has arrived:
///   master:  E_out_M(n) ≤ E_in_S(n − D_sm)        slave:  E_out_S(n) ≤ E_in_M(n − D_ms)
/// D is whatever the network did (any delay, varying, samples lost): the energies are cumulative, so the newest
/// sample that arrived carries all of it. Where a step would break the bound, the side's passivity controller
/// dissipates the excess:
///   master (impedance port: velocity in, force out): a damper on the displayed force, F' = F − α v_m;
///   slave (admittance port: force in, velocity out): the commanded velocity is reduced along the coupling force,
///   v' = v − β F_c; the slave's reference position integrates v', with a drift term that pulls it back to the
///   master's position (the drift's motion passes the same check, so it is paid for with energy that arrived).
/// The master's velocity is its position increment over the period (host/apps/teleop.cpp): a sum of F·Δx is the
/// discrete energy exactly, where a quantised encoder's differentiated velocity would be noise.
/// Without the controllers (Scheme::kPlain) the same code is the classic delayed position-force scheme: the slave's
/// reference is the master position received, the master displays the coupling force received.
///
/// Pure arithmetic, no allocation, no I/O: the teleop programs (host/apps/teleop.cpp) wire DDS around it, the
/// tests run it against a simulated delay.
#include <array>
#include <cstdint>

namespace phalanx::teleop {

using Vec3 = std::array<double, 3>;

enum class Scheme : uint8_t {
  kPlain = 0,    ///< position forward, force back, nothing else: unstable on stiff contact under delay
  kPassive = 1,  ///< the same with the TDPN passivity controllers at both ports
};
const char* schemeName(Scheme s);
bool parseScheme(const char* text, Scheme& out);

/// Energy through one port since the start: what entered the channel and what left it there, J.
struct PortEnergy {
  double in_J = 0;
  double out_J = 0;
  double dissipated_J = 0;  ///< removed by the passivity controller at this port
  uint64_t pc_active_cycles = 0;
  /// Book power P (W, positive into the channel) over dt_s.
  void add(double power_W, double dt_s);
};

/// What a side sends every cycle (the DDS sample's content, docs/teleop.md).
struct Sample {
  uint32_t seq = 0;
  uint64_t stamp_ns = 0;  ///< CLOCK_MONOTONIC of the sender when it sent
  Vec3 position_m{};      ///< master: the device's position; slave: the slave arm's
  Vec3 velocity_m_s{};    ///< for the peer's records: the slave moves its reference by position increments
  Vec3 force_N{};         ///< slave: the coupling force F_c (on the arm, towards the master's position)
  double energy_in_J = 0; ///< this side's cumulative E_in
};

/// Master side: the force to display on the operator's device from the newest slave sample.
class MasterPort {
 public:
  struct Config {
    Scheme scheme = Scheme::kPassive;
    /// The controller's damper never exceeds this: a damper computed from the velocity at the start of a period and
    /// held for it is itself unstable on a mass m above 2m/dt (it chattered at 400 on the 0.1 kg device of
    /// tests/unit/teleop_passivity_test.cpp); m/dt for about 0.1 kg at 1 kHz. The bound costs exactness: the
    /// energy the damper could not take is counted (MasterPort::energy().out_J beyond the received E_in).
    double max_damping_N_s_per_m = 100.0;
  };
  explicit MasterPort(const Config& c) : cfg_(c) {}
  /// v_m: the device's velocity this cycle; slave: the newest sample received (has_slave false before the first).
  /// Returns the force to display on the operator, N: −F_c, less what the controller dissipates.
  Vec3 step(const Vec3& v_m_s, const Sample& slave, bool has_slave, double dt_s);
  const PortEnergy& energy() const { return energy_; }

 private:
  Config cfg_;
  PortEnergy energy_;
};

/// Slave side: the arm's reference position from the newest master sample, and the coupling force on the arm.
class SlavePort {
 public:
  struct Config {
    Scheme scheme = Scheme::kPassive;
    double stiffness_N_per_m = 1000.0;  ///< coupling K_p: F_c = K_p (x_ref − x_s) − K_d v_s
    double damping_N_s_per_m = 30.0;    ///< K_d on the arm's own velocity
    double drift_gain_per_s = 5.0;      ///< kPassive: how fast the reference returns to the master's position
  };
  explicit SlavePort(const Config& c) : cfg_(c) {}
  /// x_s, v_s: the arm's state; master: the newest sample received. Returns the coupling force F_c on the arm.
  Vec3 step(const Vec3& x_s_m, const Vec3& v_s_m_s, const Sample& master, bool has_master, double dt_s);
  const PortEnergy& energy() const { return energy_; }
  const Vec3& reference() const { return x_ref_; }

 private:
  Config cfg_;
  PortEnergy energy_;
  Vec3 x_ref_{};
  Vec3 last_master_pos_{};
  uint32_t last_master_seq_ = 0;
  bool started_ = false;  ///< a master sample was used
};

/// The remote environment: a point mass (the slave arm's end effector) with viscous loss, in front of a wall, the
/// half-space x ≥ wall_x_m (x is the first coordinate of the master's position, offset to the master's start), a
/// stiff spring-damper that only pushes.
struct SlaveArm {
  struct Config {
    double mass_kg = 1.0;
    double viscous_N_s_per_m = 2.0;
    double wall_x_m = 0.015;            ///< from the master's first position
    double wall_stiffness_N_per_m = 5000.0;
    double wall_damping_N_s_per_m = 5.0;
  };
  Config cfg;
  Vec3 x_m{}, v_m_s{};
  Vec3 contact_force_N{};  ///< the wall's force on the arm (last step)
  double wall_work_J = 0;  ///< work done by the wall on the arm since the start (≤ stored spring energy)
  /// Semi-implicit Euler over dt_s under the coupling force, in substeps of at most 0.1 ms.
  void step(const Vec3& coupling_force_N, double dt_s);
  bool inContact() const { return x_m[0] > cfg.wall_x_m; }
};

}  // namespace phalanx::teleop
