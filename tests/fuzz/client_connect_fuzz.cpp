// libFuzzer target: the client channel's ConnectRequest validation (client/server.cpp checkConnectRequest), the
// bytes a local client sends when it connects. First byte: the daemon's rate and whether the device is held.
#include <algorithm>
#include <cstring>

#include "phalanx/host/client/client_port.h"

namespace client = phalanx::host::client;
namespace client_wire = phalanx::client_wire;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const uint32_t kRates[] = {1000, 500, 333, 250, 2000};
  const uint32_t rate_hz = kRates[(data[0] & 0x7F) % 5];
  const bool busy = (data[0] & 0x80) != 0;
  client_wire::ConnectRequest req;
  const size_t got = std::min(size - 1, sizeof req);
  std::memset(&req, 0, sizeof req);
  std::memcpy(&req, data + 1, got);
  std::string why;
  const client_wire::ConnectStatus st = client::checkConnectRequest(req, static_cast<long>(got), rate_hz, busy, why);
  if (st == client_wire::ConnectStatus::kOk) {
    // Accepted: a whole request, not busy, a deadline of at least two periods and at most 1 s, a known fallback.
    if (got != sizeof req || busy || req.deadline_ms * rate_hz < 2000 || req.deadline_ms > 1000 ||
        static_cast<uint8_t>(req.fallback) > 1 || !why.empty()) {
      __builtin_trap();
    }
  } else if (why.empty()) {
    __builtin_trap();  // a refusal must say why
  }
  return 0;
}
