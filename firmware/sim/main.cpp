// firmware-sim: the firmware core and a device app running on the simulated board in real time, with the
// device's physical plant inside, talking to the host over a pseudo-terminal exactly as a USB CDC board would.
// Prints "PTY <path>" on stdout once the link is up; logs events and safe-state entries on stderr.
#include <signal.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>

#include "phalanx/fw/core.h"
#include "phalanx/fw_sim/sim_device.h"
#include "phalanx/linux/fd_link.h"
#include "phalanx/linux/realtime.h"
#include "phalanx/sim/board.h"

namespace {

volatile std::sig_atomic_t g_stop = 0;
void onSignal(int) { g_stop = 1; }

class LogObserver : public phalanx::fw::CoreObserver {
 public:
  void onEvent(const phalanx::protocol::Event& e) override {
    std::fprintf(stderr, "firmware-sim: EVENT t_us=%u code=%u channel=%u detail=%u value=%g\n", e.time_us,
                 static_cast<unsigned>(e.code), e.channel, e.detail, static_cast<double>(e.value));
  }
};

}  // namespace

int main(int argc, char** argv) {
  using namespace phalanx;
  CLI::App cli{"firmware-sim - Phalanx firmware on the simulated board, linked over a pseudo-terminal"};
  std::string device = "glove5";
  unsigned tick_hz = 1000;
  unsigned substeps = 10;
  fw_sim::SimDeviceOptions dev_opt;
  bool exit_with_parent = false;
  double seconds = 0.0;
  cli.add_option("--device", device, "glove5 | sea_finger | sea_rig | pantograph");
  cli.add_option("--tick-hz", tick_hz, "firmware tick rate")->check(CLI::Range(100u, 10000u));
  cli.add_option("--substeps", substeps, "plant integration steps per tick")->check(CLI::Range(1u, 100u));
  cli.add_option("--seed", dev_opt.seed, "plant noise seed");
  cli.add_option("--scenario", dev_opt.scenario, "simulated user: still|close-open|grasp|random")
      ->check(CLI::IsMember({"still", "close-open", "grasp", "random"}));
  cli.add_option("--seconds", seconds, "stop after this long (0: until SIGTERM)")->check(CLI::Range(0.0, 86400.0));
  cli.add_flag("--exit-with-parent", exit_with_parent, "terminate when the parent process dies");
  try {
    cli.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return cli.exit(e);
  }
  if (exit_with_parent) prctl(PR_SET_PDEATHSIG, SIGTERM);
  struct sigaction sa {};
  sa.sa_handler = onSignal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);

  std::string error;
  auto dev = fw_sim::makeSimDevice(device, dev_opt, error);
  if (!dev) {
    std::fprintf(stderr, "firmware-sim: error: %s\n", error.c_str());
    return 2;
  }
  linux_hal::PtyMaster link;
  if (const std::string err = link.open(); !err.empty()) {
    std::fprintf(stderr, "firmware-sim: error: %s\n", err.c_str());
    return 3;
  }
  sim::SimBoard board(dev->pwmCount(), dev->adcCount(), dev->encoderCount(), link);
  fw::CoreConfig cfg;
  cfg.tick_rate_hz = static_cast<uint16_t>(tick_hz);
  cfg.firmware_build_id = PHALANX_BUILD_ID;
  fw::FirmwareCore core(board.board(), dev->app(), cfg);
  LogObserver observer;
  core.setObserver(&observer);

  std::printf("PTY %s\n", link.slavePath().c_str());
  std::fflush(stdout);

  const uint64_t period_us = 1000000u / tick_hz;
  const double sub_dt_s = static_cast<double>(period_us) * 1e-6 / substeps;
  linux_hal::PeriodicTimer timer(period_us * 1000u);
  uint64_t overruns = 0;
  bool was_active = false;
  const auto max_ticks = static_cast<uint64_t>(seconds * tick_hz);
  for (uint64_t n = 0; g_stop == 0 && (max_ticks == 0 || n < max_ticks); ++n) {
    overruns += timer.wait();
    for (unsigned i = 0; i < substeps; ++i) dev->plant().step(sub_dt_s, board.io());
    board.clock().advanceUs(period_us);
    const uint64_t deadline_us = core.commandDeadlineUs();
    core.tick();
    link.flush();
    // Observe the power stage itself (the simulated H-bridges), not the core's opinion of it.
    const bool active = board.io().pwm_enabled;
    if (was_active && !active) {
      std::fprintf(stderr, "firmware-sim: SAFE t_us=%llu deadline_us=%llu period_us=%llu faults=0x%04x\n",
                   static_cast<unsigned long long>(board.clock().nowUs()),
                   static_cast<unsigned long long>(deadline_us), static_cast<unsigned long long>(period_us),
                   core.faultBits());
    }
    was_active = active;
  }
  board.board().pwm->disableAll();
  dev->app().safe();
  std::fprintf(stderr,
               "firmware-sim: stopped ticks=%u overruns=%llu commands=%u rejected=%u cmd_lost=%u rx_crc=%u "
               "rx_framing=%u tx_dropped=%u faults=0x%04x\n",
               core.counters().ticks, static_cast<unsigned long long>(overruns), core.counters().commands_applied,
               core.counters().commands_rejected, core.counters().cmd_lost, core.rxStats().crc_errors,
               core.rxStats().framing_errors, core.counters().tx_dropped, core.faultBits());
  return 0;
}
