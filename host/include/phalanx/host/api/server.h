#pragma once
/// The therapist's control API: phalanxd serves JSON-lines requests on a local UNIX socket (never on a network
/// address). Access (socket_access.h, docs/security.md): the socket is created mode 0660 in a directory only its
/// owner can write, and each client's credentials are checked (the daemon's uid, root, or the API group).
/// docs/api.md is the reference of every request.
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/api/dashboard_options.h"
#include "phalanx/host/api/socket_access.h"
#include "phalanx/host/daemon.h"

namespace phalanx::host::api {

struct ServerConfig {
  std::string socket_path;
  std::string records_dir = ".";   ///< session records (.phrec) and reports (.html)
  std::string profiles_dir = ".";  ///< patient profiles <patient>.yaml
  RunOptions defaults;             ///< device, rate, … for sessions the API starts
  unsigned socket_mode = 0660;
  /// Group whose members may use the API besides the daemon's user and root; -1: the daemon's effective group.
  long api_group = -1;
  /// Devices a start request may name besides defaults.device (exact device strings, e.g. serial:/dev/ttyACM1).
  std::vector<std::string> allowed_devices;
  /// Live dashboard (docs/dashboard.md): off by default. Its URL (with the access token) is printed on stdout
  /// ("DASHBOARD <url>") and written to <socket_path>.dashboard with socket_mode.
  DashboardOptions dashboard;
};

/// Serve until SIGINT/SIGTERM; stops a running session cleanly first. Returns the process exit code.
int serve(const ServerConfig& config);

/// The request handler serve() runs (one JSON request line → the answer object), without the socket: for
/// in-process callers (tests, fuzzing). It owns its daemon state; a session it started is stopped when the last
/// copy of the handler is destroyed.
std::function<nlohmann::json(const std::string&)> makeRequestHandler(const ServerConfig& config);


}  // namespace phalanx::host::api
