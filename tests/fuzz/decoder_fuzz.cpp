// libFuzzer target: arbitrary bytes into the stream decoder and every payload decoder. Must never crash,
// hang or read out of bounds; every frame it accepts must re-encode to the same bytes.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "phalanx/protocol/codec.h"

using namespace phalanx::protocol;

template <class Msg>
static void check(const Frame& f) {
  Msg m;
  if (!decodePayload(f.payload, f.len, m)) return;
  uint8_t again[Msg::kWireSize];
  encodePayload(m, again);
  // Enum fields were validated, so a decoded message re-encodes to the bytes it came from.
  if (std::memcmp(again, f.payload, Msg::kWireSize) != 0) std::abort();
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  StreamDecoder d;
  for (size_t i = 0; i < size; ++i) {
    if (!d.push(data[i])) continue;
    const Frame& f = d.frame();
    switch (static_cast<MsgId>(f.id)) {
      case MsgId::kHello: check<Hello>(f); break;
      case MsgId::kHelloAck: check<HelloAck>(f); break;
      case MsgId::kCommand: check<Command>(f); break;
      case MsgId::kTelemetry: check<Telemetry>(f); break;
      case MsgId::kEvent: check<Event>(f); break;
      case MsgId::kClearFaults: check<ClearFaults>(f); break;
      case MsgId::kParamGet: check<ParamGet>(f); break;
      case MsgId::kParamSet: check<ParamSet>(f); break;
      case MsgId::kParamValue: check<ParamValue>(f); break;
    }
  }
  // Also treat the input as one packet body (CAN-FD / USB path).
  Frame f;
  (void)checkBody(data, size, f);
  return 0;
}
