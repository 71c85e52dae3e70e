// A spring at a chosen point for one glove finger, rendered from a libphalanx servo callback (docs/sdk.md).
//
// Each cycle: the fingertip position p from the mechanism angles (phalanx::gloveFingertip, eq 3-5), the
// spring force F = k (p0 - p), and the one component the glove can exert - along the fingertip pad normal
// n = (-sin phi, cos phi) - sent as that finger's pad-force setpoint: f = F . n (N, positive resists flexion).
// The anchor p0 is --point X_MM,Y_MM in the finger's base frame, or the first fingertip position seen.
//
//   glove_spring --socket PATH [--finger 1] [--k 300] [--point X_MM,Y_MM] [--seconds 0] [--log FILE]
// --log writes one line per command: telemetry_seq,command_force_N (what this example computed).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "phalanx/client.hpp"

namespace {

struct Args {
  std::string socket;
  int finger = 1;
  double k_N_per_m = 300.0;
  bool have_point = false;
  double x0_m = 0.0, y0_m = 0.0;
  double dx_m = 0.0, dy_m = 0.0;
  double seconds = 0.0;
  unsigned deadline_ms = 20;
  std::string log;
};

bool parse(int argc, char** argv, Args& a) {
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const char* v = argv[i + 1];
    if (key == "--socket") {
      a.socket = v;
    } else if (key == "--finger") {
      a.finger = std::atoi(v);
    } else if (key == "--k") {
      a.k_N_per_m = std::atof(v);
    } else if (key == "--point") {
      double x = 0, y = 0;
      if (std::sscanf(v, "%lf,%lf", &x, &y) != 2) return false;
      a.x0_m = x * 1e-3;
      a.y0_m = y * 1e-3;
      a.have_point = true;
    } else if (key == "--offset") {
      double x = 0, y = 0;
      if (std::sscanf(v, "%lf,%lf", &x, &y) != 2) return false;
      a.dx_m = x * 1e-3;
      a.dy_m = y * 1e-3;
    } else if (key == "--seconds") {
      a.seconds = std::atof(v);
    } else if (key == "--deadline-ms") {
      a.deadline_ms = static_cast<unsigned>(std::atoi(v));
    } else if (key == "--log") {
      a.log = v;
    } else {
      return false;
    }
  }
  return !a.socket.empty() && a.finger >= 0 && a.finger < PHALANX_GLOVE_FINGERS && a.k_N_per_m >= 0.0;
}

/// f = k (p0 - p) . n_pad(phi): the spring's pad-normal component, N.
double springPadForce(const Args& a, const std::array<double, 3>& tip) {
  const double nx = -std::sin(tip[2]), ny = std::cos(tip[2]);
  return a.k_N_per_m * ((a.x0_m - tip[0]) * nx + (a.y0_m - tip[1]) * ny);
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  if (!parse(argc, argv, a)) {
    std::fprintf(stderr, "usage: glove_spring --socket PATH [--finger 0..4] [--k N_PER_M] [--point X_MM,Y_MM] "
                         "[--offset DX_MM,DY_MM] [--seconds S] [--deadline-ms 20] [--log FILE]\n");
    return 2;
  }
  try {
    phalanx::Client client({a.socket, a.deadline_ms, phalanx::Fallback::kSafe});
    if (std::strcmp(client.device().device_name, "glove5") != 0) {
      std::fprintf(stderr, "glove_spring: the device is %s, not glove5\n", client.device().device_name);
      return 2;
    }
    std::FILE* log = a.log.empty() ? nullptr : std::fopen(a.log.c_str(), "w");
    const uint64_t cycles = static_cast<uint64_t>(a.seconds * client.device().rate_hz);
    uint64_t n = 0;
    phalanx::State last{};
    const int rc = client.runServo(
        [&](const phalanx::State& s, phalanx::Command& cmd) {
          const std::array<double, 3> tip = phalanx::gloveFingertip(s, a.finger);
          if (!a.have_point) {
            a.x0_m = tip[0] + a.dx_m;
            a.y0_m = tip[1] + a.dy_m;
            a.have_point = true;
          }
          const float f = static_cast<float>(springPadForce(a, tip));
          cmd.mode = phalanx::Mode::kSetpoint;
          cmd.setpoint.fill(0.0f);
          cmd.setpoint[static_cast<size_t>(a.finger)] = f;
          if (log != nullptr) std::fprintf(log, "%u,%.9g\n", s.telemetry_seq, static_cast<double>(f));
          return cycles == 0 || ++n < cycles;
        },
        &last);
    if (log != nullptr) std::fclose(log);
    std::printf("glove_spring: %s after %llu commands, achieved %.0f Hz, daemon limited %u, force-off cause %s (device faults 0x%04x)\n",
                rc == PHALANX_OK ? "done" : "forced off", static_cast<unsigned long long>(n),
                static_cast<double>(last.achieved_rate_hz), last.limited,
                phalanx_force_off_cause_name(last.force_off_cause), static_cast<unsigned>(last.fault_bits));
    return rc == PHALANX_OK ? 0 : 1;
  } catch (const phalanx::Error& e) {
    std::fprintf(stderr, "glove_spring: %s\n", e.what());
    return 3;
  }
}
