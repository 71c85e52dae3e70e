#pragma once
/// The therapist's control API: phalanxd serves JSON-lines requests on a local UNIX socket (never on a network
/// address). Whoever may open the socket file may use the API: it is created mode 0660, so access is the
/// daemon user and its group. docs/api.md is the reference of every request.
#include <string>

#include <nlohmann/json.hpp>

#include "phalanx/host/api/dashboard_options.h"
#include "phalanx/host/daemon.h"

namespace phalanx::host::api {

/// Default socket: $XDG_RUNTIME_DIR/phalanxd.sock, else /tmp/phalanxd-<uid>.sock.
std::string defaultSocketPath();

struct ServerConfig {
  std::string socket_path;
  std::string records_dir = ".";   ///< session records (.phrec) and reports (.html)
  std::string profiles_dir = ".";  ///< patient profiles <patient>.yaml
  RunOptions defaults;             ///< device, rate, … for sessions the API starts
  unsigned socket_mode = 0660;
  /// Live dashboard (docs/dashboard.md): off by default. Its URL (with the access token) is printed on stdout
  /// ("DASHBOARD <url>") and written to <socket_path>.dashboard with socket_mode.
  DashboardOptions dashboard;
};

/// Serve until SIGINT/SIGTERM; stops a running session cleanly first. Returns the process exit code.
int serve(const ServerConfig& config);


}  // namespace phalanx::host::api
