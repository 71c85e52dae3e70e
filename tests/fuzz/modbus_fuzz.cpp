// libFuzzer target: phalanxd's Modbus TCP server (modbus/server.cpp request handling, register_map.cpp writes),
// fed through libmodbus's own framing exactly as the server thread reads a client: the input is the byte stream
// a client sends on its connection (any number of MBAP frames), over a socketpair. First byte: the device
// (glove5, sea_finger, pantograph). Every accepted write must respect the write limits.
#include <sys/socket.h>
#include <unistd.h>

#include <cmath>
#include <memory>

#include "phalanx/host/modbus/server.h"

using namespace phalanx;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // At most 1 KiB: ≤ 128 requests, whose answers fit the socket buffer the harness does not read while the server
  // serves (more filled it and the server's send waited for ever: a harness timeout, found by the fuzzer).
  if (size < 1 || size > 1025) return 0;
  const protocol::DeviceLayout* layout = protocol::layoutFor(static_cast<protocol::DeviceType>(1 + data[0] % 3));
  host::modbus::ServerOptions opt;
  opt.writes_enabled = true;
  // libmodbus answers some malformed requests only after sleeping its response timeout (it flushes the stream):
  // 1 ms instead of 20 keeps such inputs cheap; the handling is the same.
  opt.byte_timeout_ms = 1;
  const host::modbus::WriteLimits limits{layout->setpoint_count, layout->setpoint_limit};
  host::modbus::Server server(opt, limits);
  int sv[2];
  if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0) return 0;
  timeval snd{0, 100000};  // as the server sets on every accepted client
  ::setsockopt(sv[1], SOL_SOCKET, SO_SNDTIMEO, &snd, sizeof snd);
  // The whole stream, then end of stream: the server reads until the frames end (a partial one is dropped).
  if (::write(sv[0], data + 1, size - 1) != static_cast<ssize_t>(size - 1)) __builtin_trap();
  ::shutdown(sv[0], SHUT_WR);
  if (!server.serveConnection(sv[1]).empty()) __builtin_trap();
  ::close(sv[0]);
  ::close(sv[1]);
  host::modbus::RemoteCommand cmd;
  if (server.latestCommand(cmd)) {
    for (size_t i = 0; i < cmd.setpoint.size(); ++i) {
      const float v = cmd.setpoint[i];
      if (!std::isfinite(v) || std::fabs(v) > limits.setpoint_limit) __builtin_trap();  // beyond the limit
      if (i >= limits.setpoint_count && v != 0.0f) __builtin_trap();                  // a channel it lacks
    }
  }
  return 0;
}
