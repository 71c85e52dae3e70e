#include "phalanx/host/client/client_options.h"

#include <grp.h>
#include <sys/un.h>
#include <yaml-cpp/yaml.h>

namespace phalanx::host::client {

std::string loadClientOptions(const YAML::Node& node, ClientOptions& o) {
  if (!node.IsMap()) return "client: expected a mapping (socket, group)";
  for (const auto& kv : node) {
    const std::string key = kv.first.as<std::string>();
    if (key != "socket" && key != "group") return "client." + key + ": unknown key (allowed: group, socket)";
    if (!kv.second.IsScalar()) return "client." + key + ": expected a string";
  }
  if (node["socket"]) o.socket_path = node["socket"].as<std::string>();
  if (node["group"]) o.group = node["group"].as<std::string>();
  return validateClientOptions(o);
}

std::string validateClientOptions(const ClientOptions& o) {
  if (o.socket_path.empty()) {
    return o.group.empty() ? "" : "client.group: needs client.socket (--client-socket)";
  }
  if (o.socket_path.front() != '/') return "client.socket: '" + o.socket_path + "' is not an absolute path";
  if (o.socket_path.size() >= sizeof(sockaddr_un{}.sun_path)) {
    return "client.socket: '" + o.socket_path + "' is longer than a UNIX socket path may be (107 bytes)";
  }
  if (o.socket_path.back() == '/') return "client.socket: '" + o.socket_path + "' names a directory, not a socket";
  if (!o.group.empty() && getgrnam(o.group.c_str()) == nullptr) {
    return "client.group: no group named '" + o.group + "'";
  }
  return {};
}

}  // namespace phalanx::host::client
