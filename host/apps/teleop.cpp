// phalanx-teleop: the two sides of a teleoperation pair over DDS (docs/teleop.md).
//
//   phalanx-teleop master --socket PATH [--ns lab/teleop] [--scheme passive|plain] [--seconds S] [--csv FILE]
//   phalanx-teleop remote [--ns lab/teleop] [--scheme passive|plain] [--seconds S] [--csv FILE] [--wall-x M] ...
//   both: [--domain N] [--interface IF]
//
// master: a libphalanx client of the local phalanxd driving a pantograph (the operator's pen). Every daemon cycle it
// sends the pen centre's position (from its first position) and velocity, takes the newest slave sample and
// displays the force the passivity layer gives (host/include/phalanx/host/teleop/passivity.h) as a pen wrench: the
// daemon's limits stage, client deadline and force-off causes apply as for any client (docs/sdk.md).
// remote: a simulated slave arm against a wall at 1 kHz, coupled to the master's position.
// Each prints a JSON summary on stdout at the end; --csv writes one row per cycle (the master's with the device's
// time, the remote's with the master sample it used: the rows of the two sides and of the device line up).
#include <dds/dds.h>
#include <signal.h>
#include <time.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cyclone_domain.h"
#include "phalanx/client.hpp"
#include "phalanx/host/stats.h"
#include "phalanx/host/teleop/passivity.h"
#include "ros2_msgs.h"

namespace {

using namespace phalanx;
using teleop::Sample;
using teleop::Vec3;

std::atomic<bool> g_stop{false};
void onSignal(int) { g_stop = true; }

uint64_t monoNs() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<uint64_t>(ts.tv_sec) * 1000000000ull + static_cast<uint64_t>(ts.tv_nsec);
}

struct Options {
  std::string role;
  uint32_t domain = 0;
  std::string interface;
  std::string ns = "phalanx/teleop";
  std::string scheme = "passive";
  double seconds = 0;
  double until_device_s = 0;  // master: stop once the device's clock has passed this (0: not used)
  std::string csv;
  std::string socket;       // master
  unsigned deadline_ms = 50;
  double slave_timeout_ms = 500;
  teleop::MasterPort::Config master;   // master
  teleop::SlaveArm::Config arm;        // remote
  teleop::SlavePort::Config coupling;  // remote
};

/// Why a received sample was not used (an external input: validated before it can reach a motor).
struct RxCounts {
  uint64_t received = 0, used = 0, rejected_nonfinite = 0, rejected_range = 0, rejected_stale = 0;
  nlohmann::json json() const {
    return {{"received", received}, {"used", used}, {"rejected_nonfinite", rejected_nonfinite},
            {"rejected_range", rejected_range}, {"rejected_stale", rejected_stale}};
  }
};

/// One participant, the writer of this side's topic and the reader of the other's; best effort, keep last 1.
class Link {
 public:
  std::string open(const Options& o, bool master) {
    if (std::string err = host::dds::createDomain(o.domain, o.interface, domain_); !err.empty()) return err;
    participant_ = dds_create_participant(o.domain, nullptr, nullptr);
    if (participant_ < 0) return std::string("dds: cannot create a participant: ") + dds_strretcode(participant_);
    dds_qos_t* q = dds_create_qos();
    dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
    dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
    const dds_data_representation_id_t rep[] = {DDS_DATA_REPRESENTATION_XCDR1};
    dds_qset_data_representation(q, 1, rep);
    const std::string mine = "rt/" + o.ns + (master ? "/teleop/master" : "/teleop/slave");
    const std::string theirs = "rt/" + o.ns + (master ? "/teleop/slave" : "/teleop/master");
    const dds_topic_descriptor_t* desc = &phalanx_msgs_msg_dds__TeleopSample__desc;
    const dds_entity_t tw = dds_create_topic(participant_, desc, mine.c_str(), q, nullptr);
    const dds_entity_t tr = dds_create_topic(participant_, desc, theirs.c_str(), q, nullptr);
    writer_ = tw < 0 ? tw : dds_create_writer(participant_, tw, q, nullptr);
    reader_ = tr < 0 ? tr : dds_create_reader(participant_, tr, q, nullptr);
    dds_delete_qos(q);
    if (writer_ < 0 || reader_ < 0) return "dds: cannot create the teleop topics under rt/" + o.ns;
    return {};
  }
  ~Link() {
    if (participant_ > 0) dds_delete(participant_);
    if (domain_ > 0) dds_delete(domain_);
  }
  bool send(const Sample& s) {
    phalanx_msgs_msg_dds__TeleopSample_ m{};
    m.seq = s.seq;
    m.stamp_ns = s.stamp_ns;
    for (int i = 0; i < 3; ++i) {
      m.position[i] = s.position_m[i];
      m.velocity[i] = s.velocity_m_s[i];
      m.force[i] = s.force_N[i];
    }
    m.energy_in = s.energy_in_J;
    return dds_write(writer_, &m) == DDS_RETCODE_OK;
  }
  /// The newest valid sample that arrived since the last call into newest; true if one did.
  bool take(Sample& newest, RxCounts& c) {
    void* ptr[1] = {&rx_};
    dds_sample_info_t info[1];
    bool got = false;
    for (int guard = 0; guard < 64; ++guard) {  // keep-last 1: one sample, more only if the reader raced us
      const int n = dds_take(reader_, ptr, info, 1, 1);
      if (n <= 0) break;
      if (!info[0].valid_data) continue;
      ++c.received;
      Sample s;
      if (!decode(s, c)) continue;
      if (s.seq <= last_seq_ || s.energy_in_J < last_energy_) {
        ++c.rejected_stale;  // out of order, or a peer restarted: its energy account would start again
        continue;
      }
      last_seq_ = s.seq;
      last_energy_ = s.energy_in_J;
      newest = s;
      ++c.used;
      got = true;
    }
    return got;
  }

 private:
  bool decode(Sample& s, RxCounts& c) const {
    double all[11] = {rx_.energy_in};
    for (int i = 0; i < 3; ++i) {
      all[1 + i] = rx_.position[i];
      all[4 + i] = rx_.velocity[i];
      all[7 + i] = rx_.force[i];
    }
    for (double v : all) {
      if (!std::isfinite(v)) {
        ++c.rejected_nonfinite;
        return false;
      }
    }
    for (int i = 0; i < 3; ++i) {
      // A pen workspace is centimetres, a hand moves < 10 m/s, a wearable device exerts < 100 N: anything beyond
      // is a wrong or hostile peer, not a reading.
      if (std::fabs(rx_.position[i]) > 1.0 || std::fabs(rx_.velocity[i]) > 10.0 || std::fabs(rx_.force[i]) > 1000.0) {
        ++c.rejected_range;
        return false;
      }
    }
    if (rx_.energy_in < 0.0) {
      ++c.rejected_range;
      return false;
    }
    s.seq = rx_.seq;
    s.stamp_ns = rx_.stamp_ns;
    for (int i = 0; i < 3; ++i) {
      s.position_m[i] = rx_.position[i];
      s.velocity_m_s[i] = rx_.velocity[i];
      s.force_N[i] = rx_.force[i];
    }
    s.energy_in_J = rx_.energy_in;
    return true;
  }

  dds_entity_t domain_ = 0, participant_ = 0, writer_ = 0, reader_ = 0;
  phalanx_msgs_msg_dds__TeleopSample_ rx_{};
  uint32_t last_seq_ = 0;
  double last_energy_ = 0;
};

/// Ages of the samples used (sender's stamp to this side's use), meaningful when both run on one host: the host's
/// fixed-size µs histogram (no allocation per cycle, bounded memory however long the pair runs; 1 µs bins to 2 s).
struct Ages {
  host::Histogram us{2000000};
  void add(uint64_t stamp_ns) { us.add(static_cast<double>(monoNs() - stamp_ns) * 1e-3); }
  nlohmann::json json() const {
    if (us.count() == 0) return nullptr;
    return {{"p50_ms", us.percentile(0.5) * 1e-3}, {"p99_ms", us.percentile(0.99) * 1e-3}, {"count", us.count()}};
  }
};

nlohmann::json energyJson(const teleop::PortEnergy& e, double worst_excess_J) {
  return {{"in_J", e.in_J}, {"out_J", e.out_J}, {"dissipated_J", e.dissipated_J},
          {"controller_active_cycles", e.pc_active_cycles}, {"worst_bound_excess_J", worst_excess_J}};
}

Vec3 vec(const float (&f)[3]) { return {double{f[0]}, double{f[1]}, double{f[2]}}; }

std::FILE* openCsv(const std::string& path, const char* header) {
  if (path.empty()) return nullptr;
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) throw std::runtime_error("cannot write " + path);
  std::fprintf(f, "%s\n", header);
  return f;
}

int runMaster(const Options& o, teleop::Scheme scheme) {
  Link link;
  if (std::string err = link.open(o, true); !err.empty()) {
    std::fprintf(stderr, "phalanx-teleop: %s\n", err.c_str());
    return 3;
  }
  ConnectOptions co;
  co.socket_path = o.socket;
  co.deadline_ms = o.deadline_ms;
  Client cl(co);
  if (cl.device().device_type != 3 /* pantograph, phalanx.h */) {
    std::fprintf(stderr, "phalanx-teleop: master needs a pantograph (the daemon drives another device)\n");
    return 2;
  }
  std::FILE* csv = openCsv(o.csv, "t_s,device_time_us,x_m,y_m,z_m,vx_m_s,vy_m_s,vz_m_s,fx_N,fy_N,fz_N,energy_in_J,"
                                  "energy_out_J,slave_seq,slave_age_ms");
  teleop::MasterPort::Config mc = o.master;
  mc.scheme = scheme;
  teleop::MasterPort port(mc);
  Sample slave, out;
  bool has_slave = false, started = false;
  Vec3 origin{}, x_prev{};
  RxCounts rx;
  Ages ages;
  uint64_t cycles = 0, send_errors = 0, stale_cycles = 0, last_rx_ns = 0;
  double worst_excess = 0;
  const uint64_t t0 = monoNs();
  const double dt = 1.0 / cl.device().rate_hz;
  const int rc = cl.runServo([&](const State& s, Command& cmd) {
    if (g_stop || (o.seconds > 0 && static_cast<double>(monoNs() - t0) * 1e-9 >= o.seconds)) return false;
    if (o.until_device_s > 0 && static_cast<double>(s.device_time_us) * 1e-6 >= o.until_device_s) return false;
    const Vec3 centre = vec(s.pen.centre_m);
    if (!started) origin = centre;
    started = true;
    const Vec3 x = {centre[0] - origin[0], centre[1] - origin[1], centre[2] - origin[2]};
    const uint64_t now = monoNs();
    if (link.take(slave, rx)) {
      has_slave = true;
      last_rx_ns = now;
      ages.add(slave.stamp_ns);
    }
    // The remote silent for --slave-timeout-ms (gone, or the network down): its last force is not held on the
    // pen; the port then books a zero force, and the bound still applies when samples return.
    Sample shown = slave;
    if (has_slave && static_cast<double>(now - last_rx_ns) * 1e-6 > o.slave_timeout_ms) {
      shown.force_N = {};
      ++stale_cycles;
    }
    const Vec3 F = port.step(x, shown, has_slave, dt);
    const Vec3& xf = port.position();  // filtered (passivity.h): what the port booked
    // Velocity as the position increment over the period (passivity.h says why), not the daemon's estimate.
    const Vec3 v = {(xf[0] - x_prev[0]) / dt, (xf[1] - x_prev[1]) / dt, (xf[2] - x_prev[2]) / dt};
    x_prev = xf;
    if (has_slave) worst_excess = std::max(worst_excess, port.energy().out_J - slave.energy_in_J);
    cmd.penWrench(F);
    out.seq = static_cast<uint32_t>(++cycles);
    out.stamp_ns = monoNs();
    out.position_m = x;  // unfiltered: the slave's reference gets no lag from the booking's filter
    out.velocity_m_s = v;
    out.force_N = F;
    out.energy_in_J = port.energy().in_J;
    if (!link.send(out)) ++send_errors;
    if (csv != nullptr) {
      std::fprintf(csv, "%.6f,%llu,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.5g,%.5g,%.5g,%.6g,%.6g,%u,%.3f\n",
                   static_cast<double>(out.stamp_ns - t0) * 1e-9, static_cast<unsigned long long>(s.device_time_us),
                   x[0], x[1], x[2], v[0], v[1], v[2], F[0], F[1], F[2],
                   port.energy().in_J, port.energy().out_J, slave.seq,
                   has_slave ? static_cast<double>(out.stamp_ns - slave.stamp_ns) * 1e-6 : -1.0);
    }
    return true;
  });
  cl.release();
  if (csv != nullptr) std::fclose(csv);
  nlohmann::json j = {{"role", "master"}, {"scheme", teleop::schemeName(scheme)}, {"cycles", cycles},
                      {"send_errors", send_errors}, {"rx", rx.json()}, {"slave_sample_age", ages.json()},
                      {"slave_silent_cycles", stale_cycles},
                      {"energy", energyJson(port.energy(), worst_excess)},
                      {"exit", rc == PHALANX_OK ? "ok" : "forced off"}};
  std::printf("%s\n", j.dump(2).c_str());
  return rc == PHALANX_OK ? 0 : 1;
}

int runRemote(const Options& o, teleop::Scheme scheme) {
  Link link;
  if (std::string err = link.open(o, false); !err.empty()) {
    std::fprintf(stderr, "phalanx-teleop: %s\n", err.c_str());
    return 3;
  }
  std::FILE* csv = openCsv(o.csv, "t_s,ref_x_m,arm_x_m,arm_y_m,arm_z_m,fcx_N,fcy_N,fcz_N,wall_fx_N,contact,"
                                  "energy_in_J,energy_out_J,master_seq,master_age_ms");
  teleop::SlavePort::Config pc = o.coupling;
  pc.scheme = scheme;
  teleop::SlavePort port(pc);
  teleop::SlaveArm arm;
  arm.cfg = o.arm;
  Sample master, out;
  bool has_master = false;
  RxCounts rx;
  Ages ages;
  uint64_t cycles = 0, send_errors = 0, late_wakeups = 0;
  double worst_excess = 0;
  constexpr double kDt = 1e-3;
  timespec next{};
  clock_gettime(CLOCK_MONOTONIC, &next);
  const uint64_t t0 = monoNs();
  while (!g_stop && (o.seconds <= 0 || static_cast<double>(monoNs() - t0) * 1e-9 < o.seconds)) {
    next.tv_nsec += 1000000;
    if (next.tv_nsec >= 1000000000) {
      next.tv_nsec -= 1000000000;
      ++next.tv_sec;
    }
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, nullptr);
    if (monoNs() > static_cast<uint64_t>(next.tv_sec) * 1000000000ull + static_cast<uint64_t>(next.tv_nsec) + 1000000)
      ++late_wakeups;  // a period lost to the machine: the arm's time still advances by kDt (counted, not hidden)
    if (link.take(master, rx)) {
      has_master = true;
      ages.add(master.stamp_ns);
    }
    const Vec3 Fc = port.step(arm.x_m, arm.v_m_s, master, has_master, kDt);
    if (has_master) worst_excess = std::max(worst_excess, port.energy().out_J - master.energy_in_J);
    arm.step(Fc, kDt);
    out.seq = static_cast<uint32_t>(++cycles);
    out.stamp_ns = monoNs();
    out.position_m = arm.x_m;
    out.velocity_m_s = arm.v_m_s;
    out.force_N = Fc;
    out.energy_in_J = port.energy().in_J;
    if (!link.send(out)) ++send_errors;
    if (csv != nullptr) {
      std::fprintf(csv, "%.6f,%.6g,%.6g,%.6g,%.6g,%.5g,%.5g,%.5g,%.5g,%d,%.6g,%.6g,%u,%.3f\n",
                   static_cast<double>(out.stamp_ns - t0) * 1e-9, port.reference()[0], arm.x_m[0], arm.x_m[1],
                   arm.x_m[2], Fc[0], Fc[1], Fc[2], arm.contact_force_N[0], arm.inContact() ? 1 : 0,
                   port.energy().in_J, port.energy().out_J, master.seq,
                   has_master ? static_cast<double>(out.stamp_ns - master.stamp_ns) * 1e-6 : -1.0);
    }
  }
  if (csv != nullptr) std::fclose(csv);
  nlohmann::json j = {{"role", "remote"}, {"scheme", teleop::schemeName(scheme)}, {"cycles", cycles},
                      {"late_wakeups", late_wakeups}, {"send_errors", send_errors}, {"rx", rx.json()},
                      {"master_sample_age", ages.json()}, {"energy", energyJson(port.energy(), worst_excess)},
                      {"wall_work_J", arm.wall_work_J}};
  std::printf("%s\n", j.dump(2).c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{"phalanx-teleop: the master (the local pen) or the remote side (a simulated arm and wall) of a "
               "teleoperation pair over DDS (docs/teleop.md)"};
  app.require_subcommand(1);
  auto common = [&o](CLI::App* s) {
    s->add_option("--domain", o.domain, "DDS domain id (ROS_DOMAIN_ID)")->check(CLI::Range(0u, 232u));
    s->add_option("--interface", o.interface, "network interface name or IPv4 address (empty: Cyclone's choice)");
    s->add_option("--ns", o.ns, "topic namespace of the pair: rt/<ns>/teleop/master and .../slave")->capture_default_str();
    s->add_option("--scheme", o.scheme, "passive (time-domain passivity control) | plain (none: unstable under delay)")
        ->check(CLI::IsMember({"passive", "plain"}))->capture_default_str();
    s->add_option("--seconds", o.seconds, "stop after this long (0: until SIGINT/SIGTERM)")->check(CLI::Range(0.0, 86400.0));
    s->add_option("--csv", o.csv, "write one row per cycle to this file");
  };
  CLI::App* m = app.add_subcommand("master", "the operator's side: a client of the local phalanxd (pantograph)");
  common(m);
  m->add_option("--socket", o.socket, "phalanxd's client socket (--client-socket)")->required();
  m->add_option("--until-device-s", o.until_device_s,
                "also stop once the device's own clock has passed this many seconds (a scripted run on a machine "
                "whose device clock runs slow, as an emulated one)")
      ->check(CLI::Range(0.0, 86400.0));
  m->add_option("--max-damping", o.master.max_damping_N_s_per_m,
                "the passivity controller's largest damper on the device, N·s/m (passivity.h says why it is bounded)")
      ->check(CLI::Range(1.0, 5000.0))->capture_default_str();
  m->add_option("--damping", o.master.local_damping_N_s_per_m,
                "a damper on the pen outside the channel, N·s/m (the local loop's own delay: passivity.h)")
      ->check(CLI::Range(0.0, 100.0))->capture_default_str();
  m->add_option("--position-filter", o.master.position_filter_hz,
                "low-pass on the pen position before it is booked and sent, Hz (0: none; passivity.h says why)")
      ->check(CLI::Range(0.0, 500.0))->capture_default_str();
  m->add_option("--slave-timeout-ms", o.slave_timeout_ms,
                "no slave sample for this long: the pen shows no force until one arrives (above the network's delay)")
      ->check(CLI::Range(10.0, 10000.0))->capture_default_str();
  m->add_option("--deadline-ms", o.deadline_ms, "the client deadline (docs/sdk.md)")->check(CLI::Range(2u, 1000u))->capture_default_str();
  CLI::App* r = app.add_subcommand("remote", "the remote side: a simulated slave arm against a wall, at 1 kHz");
  common(r);
  r->add_option("--wall-x", o.arm.wall_x_m, "the wall's distance along +x from the start, m")->check(CLI::Range(0.0, 0.5))->capture_default_str();
  r->add_option("--wall-stiffness", o.arm.wall_stiffness_N_per_m, "N/m")->check(CLI::Range(1.0, 1e6))->capture_default_str();
  r->add_option("--arm-mass", o.arm.mass_kg, "kg")->check(CLI::Range(0.01, 100.0))->capture_default_str();
  r->add_option("--coupling-stiffness", o.coupling.stiffness_N_per_m, "K_p of the arm's coupling to the master, N/m")
      ->check(CLI::Range(1.0, 1e5))->capture_default_str();
  r->add_option("--coupling-damping", o.coupling.damping_N_s_per_m, "K_d on the arm's velocity, N·s/m")
      ->check(CLI::Range(0.0, 1e4))->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  teleop::Scheme scheme = teleop::Scheme::kPassive;
  teleop::parseScheme(o.scheme.c_str(), scheme);
  struct sigaction sa{};
  sa.sa_handler = onSignal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  try {
    return m->parsed() ? runMaster(o, scheme) : runRemote(o, scheme);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "phalanx-teleop: %s\n", e.what());
    return 1;
  }
}
