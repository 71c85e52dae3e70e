#pragma once
/// Bilateral teleoperation over a delayed, lossy network, position forward and force back (docs/teleop.md), made
/// passive by time-domain passivity control on the time-delay power network (TDPN):
///   J. Artigas, J.-H. Ryu, C. Preusche, G. Hirzinger, "Network representation and passivity of delayed
///   teleoperation systems", IEEE/RSJ IROS 2011; the passivity observer/controller pair of B. Hannaford,
///   J.-H. Ryu, "Time-domain passivity control of haptic interfaces", IEEE Trans. Robotics and Automation 18(1), 2002.
///
/// The channel is a two-port between the master device's port (v_m, F: the force displayed on the operator) and
/// the slave's reference (v_ref, F_c: the coupling force on the arm). Each port books the energy that crosses it
/// into what entered the channel (E_in) and what left it (E_out) — the master as the force that acted over the
/// last period times the (filtered) displacement since: a sum of F·Δx is the discrete energy exactly, where a
/// quantised encoder's differentiated velocity would be noise — and sends its cumulative E_in with every sample.
/// The channel is passive while the energy leaving at each port never exceeds the energy that entered at the
/// other port and has arrived:
///   master:  E_out_M(n) ≤ E_in_S(n − D_sm)        slave:  E_out_S(n) ≤ E_in_M(n − D_ms)
/// D is whatever the network did (any delay, varying, samples lost): the energies are cumulative, so the newest
/// sample that arrived carries all of it. Where the coming period would break the bound, the side's passivity
/// controller dissipates the excess: the master's (an impedance port: velocity in, force out) with a damper on the
/// device, F' = F − α v (Hannaford & Ryu's PC); the slave's (SlavePort) on the reference's velocity. Without the
/// controllers (Scheme::kPlain) the same code is the classic delayed position-force scheme.
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
  Vec3 velocity_m_s{};    ///< for the peer's records (the ports book energy by displacement)
  Vec3 force_N{};         ///< slave: the coupling force F_c (on the arm, towards the master's position)
  double energy_in_J = 0; ///< this side's cumulative E_in
};

/// One impedance port's passivity observer and controller: books F·Δx, bounds what leaves by what arrived.
class ImpedancePort {
 public:
  ImpedancePort(Scheme scheme, double max_damping_N_s_per_m) : scheme_(scheme), max_damping_(max_damping_N_s_per_m) {}
  /// x: the device's position now, F: the force it should exert over the coming period, available_in_J: the other
  /// port's E_in that has arrived. Books the last period (the force then × the displacement since), then returns
  /// F less the damping that keeps E_out ≤ available_in_J, predicting the coming period's displacement from the
  /// last one.
  Vec3 step(const Vec3& x_m, const Vec3& F_N, double available_in_J, bool bounded, double dt_s);
  const PortEnergy& energy() const { return energy_; }

 private:
  Scheme scheme_;
  double max_damping_;
  PortEnergy energy_;
  Vec3 x_prev_{}, F_prev_{}, v_{};
  bool started_ = false;
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
    /// First-order low-pass on the device's position before it is booked, Hz (0: none). An encoder's
    /// count flickering under a steady force books energy in and out in turns: in/out are split per period, so
    /// the flicker inflates both, the master's out beyond what the slave sent (measured: 0.3 J past the bound in
    /// 20 s on the pen at rest against a 1 N force, tests/vm/teleop_test.sh), and its in into budget the slave
    /// spends. 30 Hz: the pen's 4000-count encoders flicker at up to the tick rate; a hand moves below 10 Hz.
    double position_filter_hz = 30.0;
    /// A damper on the device outside the channel (not booked): the local loop (device → daemon → this side →
    /// the slave's coupling → back) has milliseconds of delay of its own, which no network bound sees; rendering
    /// the coupling's stiffness through it needs damping (a stiffness K behind a delay T wants b > K·T/2: the
    /// ≈ 830 N/m of the coupling in series with the wall behind 3–7 ms, 1.3–3 N·s/m). Without it both schemes
    /// bounced on the wall with no network delay at all (contact 57–60 % of the hold, tests/dds/teleop_netns_test.sh
    /// on this machine); with 3 both held it. Both schemes get it: the comparison is of the channel.
    double local_damping_N_s_per_m = 3.0;
  };
  explicit MasterPort(const Config& c) : cfg_(c), port_(c.scheme, c.max_damping_N_s_per_m) {}
  /// x_m: the device's position this cycle; slave: the newest sample received (has_slave false before the first).
  /// Returns the force to display on the operator, N: −F_c, less what the controller dissipates.
  Vec3 step(const Vec3& x_m, const Sample& slave, bool has_slave, double dt_s);
  const PortEnergy& energy() const { return port_.energy(); }
  /// The position booked this cycle (after the filter). The master sends the unfiltered one: as the slave's
  /// reference the filter's lag would add to the loop's delay (it made the contact bounce without network delay).
  const Vec3& position() const { return x_f_; }

 private:
  Config cfg_;
  ImpedancePort port_;
  Vec3 x_f_{}, x_f_prev_{};
  bool filter_started_ = false;
};

/// Slave side: the arm's reference from the master samples, and its coupling F_c = K_p (x_ref − x_s) − K_d v_s.
/// An admittance port (force in, velocity out): its controller takes the excess off the reference's velocity,
/// v' = v − β F_c, and the reference integrates v'; it lags (drifts) where energy was short and a drift term
/// brings it back to the master's position, paid for by the same bound. (A damper on the arm instead, the
/// impedance form, let 0.4–0.6 J escape the bound at 50–100 ms in tests/unit/teleop_passivity_test.cpp: the
/// stiff coupling's force jumps faster than a bounded damper on a 1 kg arm can take it.)
class SlavePort {
 public:
  struct Config {
    Scheme scheme = Scheme::kPassive;
    double stiffness_N_per_m = 1000.0;  ///< coupling K_p
    double damping_N_s_per_m = 30.0;    ///< K_d on the arm's own velocity
    double drift_gain_per_s = 5.0;      ///< kPassive: how fast the reference returns to the master's position
  };
  explicit SlavePort(const Config& c) : cfg_(c) {}
  /// x_s, v_s: the arm's state; master: the newest sample received. Returns the coupling force on the arm; before
  /// the first master sample the arm is held where it is.
  Vec3 step(const Vec3& x_s_m, const Vec3& v_s_m_s, const Sample& master, bool has_master, double dt_s);
  const PortEnergy& energy() const { return energy_; }
  const Vec3& reference() const { return x_ref_; }

 private:
  Config cfg_;
  PortEnergy energy_;
  Vec3 x_ref_{};
  Vec3 last_master_pos_{};
  uint32_t last_master_seq_ = 0;
  bool held_ = false;
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
