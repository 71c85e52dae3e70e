// Writes the binary seed inputs of the fuzz targets that a text editor cannot make: protocol frames (decoder),
// CAN frames in every flavour as the real encoder maps them (can), a session record as the real writer writes
// it (record). Usage: make_seeds CORPUS_DIR (tests/fuzz/corpus); run by hand when the formats change.
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "phalanx/host/record/record_reader.h"
#include "phalanx/host/record/record_writer.h"
#include "phalanx/protocol/can.h"
#include "phalanx/protocol/codec.h"

using namespace phalanx;
using namespace phalanx::protocol;

namespace {

void put(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()),
                                              static_cast<std::streamsize>(bytes.size()));
}

template <class Msg>
void appendFrame(std::vector<uint8_t>& out, const Msg& m) {
  uint8_t buf[kMaxEncodedFrame];
  const size_t n = encodeFrame(m, buf);
  out.insert(out.end(), buf, buf + n);
}

Command command(const DeviceLayout& l) {
  Command c;
  c.seq = 7;
  c.timeout_ms = 50;
  c.mode = Mode::kSetpoint;
  c.channel_count = l.setpoint_count;
  for (uint8_t i = 0; i < l.setpoint_count; ++i) {
    c.setpoint[i] = 0.1f * static_cast<float>(i + 1);
    c.gain_scale_permille[i] = 1000;
  }
  return c;
}

Telemetry telemetry(const DeviceLayout& l) {
  Telemetry t;
  t.time_us = 1000;
  t.seq = 3;
  t.mode = Mode::kSetpoint;
  for (uint8_t i = 0; i < l.sample_count; ++i) t.sample[i] = static_cast<int16_t>(100 * i);
  return t;
}

// A CAN fuzz input: the selector byte (flavour, role, device) and the frames of the messages.
template <class Msg>
void appendCan(std::vector<uint8_t>& out, can::Mapper& enc, const Msg& m) {
  uint8_t payload[Msg::kWireSize];
  encodePayload(m, payload);
  can::CanFrame frames[can::kMaxFramesPerMessage];
  can::EncodeStatus st{};
  const size_t n = enc.encode(static_cast<uint8_t>(Msg::kId), payload, Msg::kWireSize, frames, st);
  for (size_t i = 0; i < n; ++i) {
    const uint16_t word = static_cast<uint16_t>(frames[i].id | (frames[i].fd ? 0x800u : 0u));
    out.push_back(static_cast<uint8_t>(word & 0xFF));
    out.push_back(static_cast<uint8_t>(word >> 8));
    out.push_back(frames[i].len);
    out.insert(out.end(), frames[i].data, frames[i].data + frames[i].len);
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_seeds CORPUS_DIR\n");
    return 2;
  }
  const std::string dir = argv[1];
  const DeviceType types[] = {DeviceType::kGlove5, DeviceType::kSeaFinger, DeviceType::kPantograph};
  {
    std::vector<uint8_t> s;
    Hello h;
    appendFrame(s, h);
    HelloAck a;
    a.device_type = DeviceType::kGlove5;
    a.tick_rate_hz = 1000;
    appendFrame(s, a);
    appendFrame(s, command(kGlove5Layout));
    appendFrame(s, telemetry(kGlove5Layout));
    put(dir + "/decoder/hello-ack-command-telemetry", s);
  }
  for (unsigned flavor = 0; flavor < 3; ++flavor) {
    for (DeviceType type : types) {
      const DeviceLayout& l = *layoutFor(type);
      const unsigned dev = static_cast<unsigned>(type);
      // To the device: commands (the device knows itself).
      {
        can::Mapper enc(static_cast<can::Flavor>(flavor), can::Role::kHost, 5);
        enc.setDevice(type, 1000);
        std::vector<uint8_t> s{static_cast<uint8_t>(flavor + 3 * 1 + 6 * dev)};
        appendCan(s, enc, Hello{});
        Command c = command(l);
        appendCan(s, enc, c);
        c.seq = 8;
        appendCan(s, enc, c);
        put(dir + "/can/to-device-f" + std::to_string(flavor) + "-" + l.name, s);
      }
      // To the host, which learns the device from the HelloAck.
      {
        can::Mapper enc(static_cast<can::Flavor>(flavor), can::Role::kDevice, 5);
        enc.setDevice(type, 1000);
        std::vector<uint8_t> s{static_cast<uint8_t>(flavor)};
        HelloAck a;
        a.device_type = type;
        a.tick_rate_hz = 1000;
        a.setpoint_count = l.setpoint_count;
        a.sample_count = l.sample_count;
        appendCan(s, enc, a);
        Telemetry t = telemetry(l);
        appendCan(s, enc, t);
        t.seq = 4;
        appendCan(s, enc, t);
        put(dir + "/can/to-host-f" + std::to_string(flavor) + "-" + l.name, s);
      }
    }
  }
  {
    const std::string path = dir + "/record/three-cycles.phrec";
    std::remove(path.c_str());
    host::record::RecordWriter w;
    if (!w.open(path, {{"device", "glove5"}, {"samples", {"a", "b"}}, {"aux", {"x"}}}).empty()) return 1;
    for (int i = 0; i < 3; ++i) {
      host::record::CycleRecord c;
      c.host_ns = 1000000ull * static_cast<uint64_t>(i);
      c.t_s = 0.001 * i;
      c.tel_seq = static_cast<uint16_t>(i);
      c.sample_count = 2;
      c.setpoint_count = 1;
      c.aux_count = 1;
      c.sample[0] = 0.5f * static_cast<float>(i);
      w.pushCycle(c);
    }
    w.pushEvent(0.002, "api-exercise", {{"exercise", "assessment"}});
    w.close(nlohmann::json{{"ok", true}});
  }
  return 0;
}
