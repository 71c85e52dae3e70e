// Cost of one sea_finger firmware tick on the host (sense + control of both SEAs, both controllers), on a simulated
// board whose counts change every tick. A regression guard for the MCU budget (1 ms tick); the target cost is
// measured on the Cortex-M4 by the MCU cycle bench, not here.
//
//   sea_firmware_bench --benchmark_repetitions=10 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cmath>

#include "phalanx/apps/sea_finger.h"
#include "phalanx/sea/board.h"
#include "phalanx/sim/board.h"

namespace {

using namespace phalanx;
namespace board = phalanx::sea::board;

void tick(benchmark::State& state, apps::SeaControllerKind kind) {
  sim::BytePipe pipe;
  sim::SimBoard sim(board::kPwmChannelCount, board::kAdcChannelCount, board::kEncoderChannelCount, pipe.end(0));
  for (auto& a : sim.io().adc) a = board::kAdcMidCounts;
  auto cfg = apps::seaFingerDefaultConfig();
  cfg.controller = kind;
  apps::SeaFingerApp app(apps::seaFingerDefaultCalibration(), cfg);
  app.init(sim.board());
  while (!app.zeroed()) app.sense(1e-3f);
  protocol::Command cmd;
  cmd.mode = protocol::Mode::kSetpoint;
  cmd.channel_count = 2;
  for (auto& g : cmd.gain_scale_permille) g = 1000;
  int k = 0;
  for (auto _ : state) {
    // A 0.5 Hz sine in the counts and the setpoints (so the play model and the inverse switch sides).
    const float s = std::sin(6.2831853f * 0.5f * 1e-3f * static_cast<float>(k++));
    sim.io().encoder[0] = static_cast<int32_t>(3000.0f * s);
    sim.io().encoder[1] = static_cast<int32_t>(-2000.0f * s);
    sim.io().adc[board::kAdcFirstJoint] = board::kAdcMidCounts + static_cast<int32_t>(40.0f * s);
    cmd.setpoint[0] = 0.3f * s;
    cmd.setpoint[1] = -0.1f * s;
    benchmark::DoNotOptimize(app.sense(1e-3f));
    benchmark::DoNotOptimize(app.control(cmd, 1e-3f));
  }
}

void BM_SeaFingerTickOurs(benchmark::State& state) { tick(state, apps::SeaControllerKind::kOurs); }
void BM_SeaFingerTickPaper(benchmark::State& state) { tick(state, apps::SeaControllerKind::kPaper); }
BENCHMARK(BM_SeaFingerTickOurs);
BENCHMARK(BM_SeaFingerTickPaper);

}  // namespace
