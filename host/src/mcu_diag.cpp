#include "phalanx/host/mcu_diag.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <map>

#include "../../firmware/mcu/include/phalanx/fw_mcu/board_diag.h"
#include "phalanx/host/session.h"
#include "phalanx/linux/fd_link.h"
#include "phalanx/linux/realtime.h"

namespace phalanx::host {

namespace {
struct DiagName {
  uint16_t id;
  const char* name;
  bool integer = true;  ///< a count: carried as an f32 parameter, printed as the integer it is
};
namespace p = fw_mcu::diag_param;
constexpr DiagName kDiagNames[] = {
    {p::kTickCount, "tick_count"},   {p::kTickWorst, "tick_worst"},     {p::kTickMedian, "tick_median"},
    {p::kTickP99, "tick_p99"},       {p::kTickWorstTimer, "tick_worst_timer_counts"},
    {p::kTickUnitNs, "tick_unit_ns", false}, {p::kOverruns, "overruns"},       {p::kPlantMs, "plant_ms"},
    {p::kRxOverflows, "rx_overflows"}, {p::kLinkKind, "link_kind"},
};
}  // namespace

std::string handshakeBoard(linux_hal::FdLink& link, HostSession& session, double timeout_s,
                           protocol::DeviceType expected, const std::string& what) {
  return session.handshakeWithin(timeout_s, expected, what, [&] { link.flush(); });
}

nlohmann::json readMcuDiagnostics(const std::string& path, double timeout_s, std::string& error) {
  linux_hal::SerialLink link;
  if (std::string err = link.open(path, 115200); !err.empty()) {
    error = err;
    return {};
  }
  HostSession session(link);
  const uint64_t timeout_ns = static_cast<uint64_t>(timeout_s * 1e9);
  if (std::string err = handshakeBoard(link, session, timeout_s, protocol::DeviceType::kAny, path); !err.empty()) {
    error = err;
    return {};
  }
  std::map<uint16_t, float> values;
  for (const DiagName& d : kDiagNames) {
    // Telemetry keeps arriving (1 kHz) while we wait: poll() consumes it; the answer is the next ParamValue with
    // this id.
    session.sendParamGet(d.id);
    link.flush();
    const uint64_t t1 = linux_hal::monotonicNs();
    while (!(session.lastParamValid() && session.lastParam().param_id == d.id)) {
      if (linux_hal::monotonicNs() - t1 > timeout_ns) {
        error = std::string("no answer to ParamGet ") + d.name;
        return {};
      }
      usleep(500);
      session.poll(linux_hal::monotonicNs());
    }
    if (session.lastParam().status != protocol::ParamStatus::kOk) {
      error = std::string("device refused ParamGet ") + d.name + " (status " +
              std::to_string(static_cast<int>(session.lastParam().status)) + "): not an MCU board?";
      return {};
    }
    values[d.id] = session.lastParam().value;
  }
  return mcuDiagJson(session.layout()->name, session.deviceInfo(), values);
}

nlohmann::json mcuDiagJson(const std::string& device_type, const protocol::HelloAck& ack,
                           const std::map<uint16_t, float>& values) {
  nlohmann::json out;
  out["device_type"] = device_type;
  // The firmware's identity as its handshake carries it: the build id is the git hash it was built from.
  char build[16];
  std::snprintf(build, sizeof build, "%08x", static_cast<unsigned>(ack.firmware_build_id));
  out["firmware"] = {{"build_id", build}, {"protocol_version", ack.protocol_version}, {"tick_rate_hz", ack.tick_rate_hz}};
  nlohmann::json params = nlohmann::json::object();
  for (const DiagName& d : kDiagNames) {
    const auto it = values.find(d.id);
    if (it == values.end()) continue;
    const float v = it->second;
    if (d.integer && std::isfinite(v) && v >= 0.0f) params[d.name] = static_cast<uint64_t>(std::llround(v));
    else params[d.name] = v;
  }
  out["params"] = params;
  return out;
}

}  // namespace phalanx::host
