#pragma once
/// Options of the live dashboard (docs/dashboard.md): off by default; loopback only unless allow_remote.
#include <cstdint>
#include <string>

namespace phalanx::host::api {

struct DashboardOptions {
  bool enabled = false;
  std::string address = "127.0.0.1";  ///< an IPv4 or IPv6 literal (no host names: no resolver in the daemon)
  uint16_t port = 8080;               ///< 0: any free port (printed at start; tests)
  /// A non-loopback address is refused unless this is set (config key dashboard.allow_remote only: the dashboard
  /// carries patient data and session controls, and HTTP here is unencrypted).
  bool allow_remote = false;
};

/// "ADDRESS:PORT" or "[IPv6]:PORT" → options (enabled). "" or the problem, naming the option.
std::string parseDashboardSpec(const std::string& spec, DashboardOptions& out);
/// "" or the first problem (address not a literal, non-loopback without allow_remote).
std::string validateDashboardOptions(const DashboardOptions& opt);
/// True for 127.0.0.0/8 and ::1.
bool isLoopbackAddress(const std::string& address);

}  // namespace phalanx::host::api
