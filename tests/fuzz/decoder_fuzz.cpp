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
      case MsgId::kUpdateBegin: check<UpdateBegin>(f); break;
      case MsgId::kUpdateData: check<UpdateData>(f); break;
      case MsgId::kUpdateCommit: check<UpdateCommit>(f); break;
      case MsgId::kUpdateStatus: check<UpdateStatus>(f); break;
    }
  }
  // feed() over the same bytes (in runs of 1 to 16, the split taken from the first byte) must report the same
  // frames and counters as push() byte by byte.
  {
    StreamDecoder by_byte;
    StreamDecoder by_run;
    const size_t step = size > 0 ? 1 + data[0] % 16 : 1;
    size_t frames_byte = 0;
    size_t frames_run = 0;
    for (size_t i = 0; i < size; ++i) frames_byte += by_byte.push(data[i]) ? 1 : 0;
    for (size_t i = 0; i < size; i += step) {
      const uint8_t* p = data + i;
      const uint8_t* end = data + (i + step < size ? i + step : size);
      while (p < end) {
        const uint8_t* before = p;
        frames_run += by_run.feed(p, end) ? 1 : 0;
        if (p <= before || p > end) std::abort();
      }
    }
    const DecodeStats& a = by_byte.stats();
    const DecodeStats& b = by_run.stats();
    if (frames_byte != frames_run || a.frames_ok != b.frames_ok || a.crc_errors != b.crc_errors ||
        a.framing_errors != b.framing_errors || a.unknown_id != b.unknown_id || a.bad_length != b.bad_length) {
      std::abort();
    }
  }
  // Also treat the input as one packet body (CAN-FD / USB path).
  Frame f;
  (void)checkBody(data, size, f);
  return 0;
}
