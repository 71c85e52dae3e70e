#include "phalanx/host/lockstep.h"

#include <atomic>

#include "phalanx/host/command_limits.h"

namespace phalanx::host {
namespace {
std::atomic<uint64_t> g_rigs{0}, g_simulated_us{0}, g_wall_ns{0};

fw::CoreConfig coreConfig(const fw_sim::SimDevice& device, const LockstepOptions& options) {
  fw::CoreConfig cfg{options.tick_hz, 0, 4 * protocol::kMaxEncodedFrame};
  cfg.device_variant = device.variant();
  return cfg;
}
}  // namespace

LockstepRig::LockstepRig(fw_sim::SimDevice& device, Controller& controller, const LockstepOptions& options)
    : device_(device),
      controller_(controller),
      opt_(options),
      board_(device.pwmCount(), device.adcCount(), device.encoderCount(), pipe_.end(0)),
      core_(board_.board(), device.app(), coreConfig(device, options)),
      session_(pipe_.end(1)),
      host_every_(options.host_every_ticks > 0 ? options.host_every_ticks : 1u) {
  cmd_.timeout_ms = opt_.command_timeout_ms;
  cmd_.channel_count = device.app().layout().setpoint_count;
  for (auto& g : cmd_.gain_scale_permille) g = 1000;
}

LockstepTally lockstepTally() { return {g_rigs.load(), g_simulated_us.load(), g_wall_ns.load()}; }

LockstepRig::~LockstepRig() {
  const auto wall = std::chrono::steady_clock::now() - born_;
  g_rigs.fetch_add(1);
  g_simulated_us.fetch_add(board_.clock().nowUs());
  g_wall_ns.fetch_add(static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(wall).count()));
}

std::string LockstepRig::handshake() {
  session_.sendHello(1, device_.app().layout().type);
  for (unsigned i = 0; i < 10 * host_every_ && session_.handshake() == HandshakeResult::kPending; ++i) step();
  if (session_.handshake() != HandshakeResult::kOk) return session_.handshakeError();
  for (const auto& [id, value] : controller_.startupParams()) {
    session_.sendParamSet(id, value);
    for (unsigned i = 0; i < host_every_; ++i) step();
    if (!session_.lastParamValid() || session_.lastParam().status != protocol::ParamStatus::kOk) {
      return "device refused start-up parameter " + std::to_string(id);
    }
  }
  run(controller_.startupSettleS());
  started_ = true;
  return {};
}

void LockstepRig::step() {
  const uint64_t period_us = 1000000u / opt_.tick_hz;
  const double sub_dt_s = static_cast<double>(period_us) * 1e-6 / opt_.substeps;
  device_.plant().advance(sub_dt_s, opt_.substeps, board_.io());
  if (io_hook_) io_hook_(board_.io());
  board_.clock().advanceUs(period_us);
  core_.tick();
  if (++ticks_ % host_every_ != 0) return;
  const uint64_t now_ns = board_.clock().nowUs() * 1000u;
  session_.poll(now_ns);
  if (!started_ || !host_connected_ || !session_.hasTelemetry()) return;
  if (stopped_) {
    makeSafe(cmd_);
  } else {
    controller_.update(session_.latest(), timeS(), static_cast<double>(period_us * host_every_) * 1e-6, cmd_);
  }
  cmd_.channel_count = device_.app().layout().setpoint_count;
  session_.sendCommand(cmd_, now_ns);
}

void LockstepRig::run(double seconds) {
  const auto n = static_cast<long>(seconds * opt_.tick_hz + 0.5);
  for (long i = 0; i < n; ++i) step();
}

}  // namespace phalanx::host
