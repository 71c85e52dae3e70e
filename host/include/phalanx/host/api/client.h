#pragma once
/// Client side of the control API (the `phalanx` CLI uses it).
#include <string>

#include <nlohmann/json.hpp>

namespace phalanx::host::api {

/// Sends one request line and reads one response line. Returns "" or a connection error (the daemon's own
/// refusals come back in response["error"]). The server must run as root or as the caller's uid, or as
/// `trusted_uid` when that is >= 0 (socket_access.h); anything else is refused before the request is sent.
std::string call(const std::string& socket_path, const nlohmann::json& request, nlohmann::json& response,
                 int timeout_ms = 15000, long trusted_uid = -1);
/// Same with a raw line (for tests of malformed requests).
std::string callRaw(const std::string& socket_path, const std::string& line, std::string& response_line,
                    int timeout_ms = 15000, long trusted_uid = -1);

}  // namespace phalanx::host::api
