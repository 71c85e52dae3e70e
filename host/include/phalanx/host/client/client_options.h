#pragma once
/// phalanxd's client channel settings (YAML key `client`, option --client-socket / --client-group; docs/sdk.md).
#include <string>

namespace YAML {
class Node;
}

namespace phalanx::host::client {

struct ClientOptions {
  /// The control socket's path (empty: no client channel). Its directory is created 0700 (0750 with a group) if
  /// missing and must not be writable by others.
  std::string socket_path;
  /// Members of this group may connect besides the daemon's own user and root (empty: none).
  std::string group;
};

/// Read the `client` mapping into o. "" or "client.<key>: <problem>".
std::string loadClientOptions(const YAML::Node& node, ClientOptions& o);
/// "" or the first problem, naming the key.
std::string validateClientOptions(const ClientOptions& o);

}  // namespace phalanx::host::client
