// libFuzzer target: the CAN mapping's decoder (common/src/protocol/can.cpp) in every flavour (classic with its
// split messages, CAN-FD whole messages, CAN-FD compact) and both directions, with the device known or still to
// be learnt from a HelloAck. First byte: flavour, role, device; then frames: id (2 bytes, little endian: 11-bit
// identifier, bit 11 FD, bit 12 extended, bit 13 remote), length, data. A delivered message must have its wire
// size and decode; a frame is counted exactly once (accepted or under one rejection counter).
#include <algorithm>
#include <cstring>

#include "phalanx/protocol/can.h"
#include "phalanx/protocol/codec.h"

using namespace phalanx::protocol;

namespace {

template <class Msg>
void decodeOne(const uint8_t* p, size_t len) {
  Msg m;
  (void)decodePayload(p, len, m);
}

void decodeAs(uint8_t id, const uint8_t* p, size_t len) {
  switch (static_cast<MsgId>(id)) {
    case MsgId::kHello: decodeOne<Hello>(p, len); break;
    case MsgId::kHelloAck: decodeOne<HelloAck>(p, len); break;
    case MsgId::kCommand: decodeOne<Command>(p, len); break;
    case MsgId::kTelemetry: decodeOne<Telemetry>(p, len); break;
    case MsgId::kEvent: decodeOne<Event>(p, len); break;
    case MsgId::kClearFaults: decodeOne<ClearFaults>(p, len); break;
    case MsgId::kParamGet: decodeOne<ParamGet>(p, len); break;
    case MsgId::kParamSet: decodeOne<ParamSet>(p, len); break;
    case MsgId::kParamValue: decodeOne<ParamValue>(p, len); break;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const auto flavor = static_cast<can::Flavor>(data[0] % 3);
  const auto role = static_cast<can::Role>((data[0] / 3) % 2);
  const unsigned device = (data[0] / 6) % 4;  // 0: not known yet
  const uint8_t node = 5;
  can::Mapper m(flavor, role, node);
  if (device != 0) m.setDevice(static_cast<DeviceType>(device), 1000);
  uint32_t frames = 0;
  for (size_t i = 1; i + 3 <= size;) {
    can::CanFrame f;
    const uint16_t word = static_cast<uint16_t>(data[i] | (data[i + 1] << 8));
    f.id = word & 0x7FFu;
    f.fd = (word & 0x800u) != 0;
    f.extended = (word & 0x1000u) != 0;
    f.remote = (word & 0x2000u) != 0;
    f.len = static_cast<uint8_t>(data[i + 2] % 65);
    i += 3;
    const size_t n = std::min<size_t>(f.len, size - i);
    std::memcpy(f.data, data + i, n);
    i += n;
    uint8_t msg_id = 0;
    uint8_t payload[64];
    size_t len = 0;
    ++frames;
    if (m.decode(f, msg_id, payload, len)) {
      const size_t want = wireSize(msg_id);
      if (want == 0 || len != want) __builtin_trap();  // not a message, or not its wire size
      decodeAs(msg_id, payload, len);  // the payload decoders see what the mapping delivered
    }
    const can::RxStats& s = m.stats();
    // Classic parts count as frames_ok; a part discarded later (sequence) was counted once when it arrived and
    // once when dropped, so the sum may exceed the frames, never fall short of them.
    if (s.frames_ok + s.total_rejected() < frames) __builtin_trap();
  }
  return 0;
}
