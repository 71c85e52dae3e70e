#include "phalanx/host/can_budget.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <vector>

#include "phalanx/protocol/can.h"
#include "phalanx/protocol/codec.h"

namespace phalanx::host {

using namespace protocol;
using namespace protocol::can;

namespace {

/// Frames of one tick of a device on one flavour, straight from the mapping: the command (host) and the
/// telemetry (device). Classic telemetry rotates its sample groups, so `tick` selects which groups go out.
std::vector<CanFrame> tickFrames(const DeviceLayout& layout, Mapper& host, Mapper& dev) {
  std::vector<CanFrame> frames;
  CanFrame out[kMaxFramesPerMessage];
  EncodeStatus st;
  Command c;
  c.timeout_ms = 20;
  c.mode = Mode::kSetpoint;
  c.channel_count = layout.setpoint_count;
  for (uint8_t i = 0; i < layout.setpoint_count; ++i) c.gain_scale_permille[i] = 1000;
  uint8_t cp[Command::kWireSize];
  encodePayload(c, cp);
  size_t n = host.encode(static_cast<uint8_t>(MsgId::kCommand), cp, sizeof cp, out, st);
  frames.insert(frames.end(), out, out + n);
  Telemetry t;
  uint8_t tp[Telemetry::kWireSize];
  encodePayload(t, tp);
  n = dev.encode(static_cast<uint8_t>(MsgId::kTelemetry), tp, sizeof tp, out, st);
  frames.insert(frames.end(), out, out + n);
  return frames;
}

nlohmann::json flavourLoad(const DeviceLayout& layout, Flavor flavor, double rate_hz, double nominal, double data) {
  Mapper host(flavor, Role::kHost, 1), dev(flavor, Role::kDevice, 1);
  host.setDevice(layout.type, static_cast<uint16_t>(rate_hz));
  dev.setDevice(layout.type, static_cast<uint16_t>(rate_hz));
  // Average over enough ticks for the classic group rotation to come round (7 groups at most): 84 = lcm(1..7)·…
  constexpr int kTicks = 84;
  double worst = 0, none = 0, frames = 0, bytes = 0;
  for (int k = 0; k < kTicks; ++k) {
    for (const CanFrame& f : tickFrames(layout, host, dev)) {
      worst += frameTimeS(f, nominal, data, true);
      none += frameTimeS(f, nominal, data, false);
      frames += 1;
      bytes += f.len;
    }
  }
  return {{"frames_per_tick", frames / kTicks},
          {"data_bytes_per_tick", bytes / kTicks},
          {"load_pct_worst_stuffing", 100.0 * worst / kTicks * rate_hz},
          {"load_pct_no_stuffing", 100.0 * none / kTicks * rate_hz}};
}

}  // namespace

nlohmann::json canBudget(double rate_hz, double nominal_bps) {
  nlohmann::json out = nlohmann::json::object();
  for (const DeviceLayout* l : {&kGlove5Layout, &kSeaFingerLayout, &kPantographLayout}) {
    const ClassicProfile prof = classicProfile(l->type);
    const int groups = (l->sample_count + 3) / 4;
    out[l->name] = {
        {"classic", flavourLoad(*l, Flavor::kClassic, rate_hz, nominal_bps, nominal_bps)},
        {"classic_sample_rate_hz", rate_hz * prof.groups_per_tick / groups},
        {"fd_same_rate", flavourLoad(*l, Flavor::kFd, rate_hz, nominal_bps, nominal_bps)},
        {"fd_5x_data_rate", flavourLoad(*l, Flavor::kFd, rate_hz, nominal_bps, 5.0 * nominal_bps)},
        {"fd_compact_same_rate", flavourLoad(*l, Flavor::kFdCompact, rate_hz, nominal_bps, nominal_bps)},
        {"fd_compact_5x_data_rate", flavourLoad(*l, Flavor::kFdCompact, rate_hz, nominal_bps, 5.0 * nominal_bps)},
        // Compact FD: each tick carries a window of K of the S samples, rotating by K.
        {"fd_compact_sample_rate_hz", rate_hz * compactWindow(l->sample_count) / l->sample_count},
    };
  }
  return {{"rate_hz", rate_hz}, {"nominal_bps", nominal_bps}, {"devices", out}};
}

nlohmann::json canLoadFromLog(const std::string& path, double nominal_bps, double data_bps) {
  std::ifstream in(path);
  if (!in) return {{"error", "cannot read " + path}};
  std::string line;
  double t_first = -1, t_last = -1, worst = 0, none = 0;
  uint64_t frames = 0, fd_frames = 0, error_frames = 0;
  while (std::getline(in, line)) {
    // "(1700000000.123456) vcan0 041##1<hex>"  or  "(…) vcan0 101#<hex>"
    double ts;
    char iface[32], frame[300];
    if (std::sscanf(line.c_str(), "(%lf) %31s %299s", &ts, iface, frame) != 3) continue;
    const char* hash = std::strchr(frame, '#');
    if (hash == nullptr) continue;
    CanFrame f;
    const std::string id(frame, static_cast<size_t>(hash - frame));
    const unsigned long idv = std::strtoul(id.c_str(), nullptr, 16);
    if (id.size() == 8 && (idv & 0x20000000ul)) {
      ++error_frames;  // error frames are reports from the controller, not bus traffic
      continue;
    }
    f.extended = id.size() == 8;
    const char* hex = hash + 1;
    if (*hex == '#') {
      f.fd = true;
      hex += 2;  // "##<flags>"
    } else if (*hex == 'R') {
      f.remote = true;
      hex = "";
    }
    f.len = static_cast<uint8_t>(std::strlen(hex) / 2);
    if (f.extended) continue;  // the protocol uses 11-bit identifiers only; the model is for those
    const double bus_data = f.fd ? data_bps : nominal_bps;
    worst += frameTimeS(f, nominal_bps, bus_data, true);
    none += frameTimeS(f, nominal_bps, bus_data, false);
    ++frames;
    if (f.fd) ++fd_frames;
    if (t_first < 0) t_first = ts;
    t_last = ts;
  }
  const double span = t_last - t_first;
  if (frames < 2 || span <= 0) return {{"error", "fewer than two frames in " + path}};
  return {{"frames", frames},         {"fd_frames", fd_frames},
          {"error_frames", error_frames}, {"seconds", span},
          {"frames_per_s", static_cast<double>(frames) / span},
          {"load_pct_worst_stuffing", 100.0 * worst / span},
          {"load_pct_no_stuffing", 100.0 * none / span}};
}

}  // namespace phalanx::host
