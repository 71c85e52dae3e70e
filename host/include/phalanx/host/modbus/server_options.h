#pragma once
/// phalanxd's Modbus TCP server settings (YAML key `modbus`, docs/modbus.md).
#include <cstdint>
#include <string>

namespace YAML {
class Node;
}

namespace phalanx::host::modbus {

struct ServerOptions {
  bool enabled = false;              ///< off by default
  std::string address = "127.0.0.1"; ///< loopback unless configured
  unsigned port = 1502;              ///< 502 needs root; 0 picks a free port (logged)
  unsigned max_clients = 32;         ///< connections beyond are closed at accept
  bool writes_enabled = false;       ///< read-only unless enabled
  double setpoint_limit = 0.0;       ///< |setpoint| accepted from Modbus; 0: the device layout's limit. Never above it
  unsigned command_timeout_ms = 500; ///< Modbus control goes safe if no write arrives for this long; 0: never
  unsigned byte_timeout_ms = 20;     ///< a started frame must complete within this (one slow client stalls the
                                     ///< server thread at most this long; never the loop)
};

/// Read the `modbus` mapping into o. Returns "" or "<key>: <problem>" (key relative to the top level).
std::string loadServerOptions(const YAML::Node& node, ServerOptions& o);
/// Range checks; "" or the first problem, naming the key.
std::string validateServerOptions(const ServerOptions& o);

}  // namespace phalanx::host::modbus
