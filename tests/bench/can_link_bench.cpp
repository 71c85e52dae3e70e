// Host-side cost of the CAN transport per message: the mapping alone, and the whole CanLink path (mapping,
// user-space queue, write/recvmsg system calls) over a seqpacket socketpair carrying struct can(fd)_frame.
// Time: build/host/bin/can_link_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
// Instructions (user space only; the kernel's share is not counted by callgrind), per iteration = Ir / 20000:
//   host tick: --toggle-collect='*CanLink::send*' --toggle-collect='*CanLink::receive*'; mapping: '*BM_Mapping*'
//   valgrind --tool=callgrind --collect-atstart=no --toggle-collect=... --callgrind-out-file=/tmp/cg.out
//     build/host/bin/can_link_bench --benchmark_filter=<name>      then: callgrind_annotate /tmp/cg.out | head
#include <benchmark/benchmark.h>
#include <sys/socket.h>
#include <linux/can.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>

#include "phalanx/linux/can_link.h"
#include "phalanx/protocol/can.h"
#include "phalanx/protocol/codec.h"

using namespace phalanx;
using namespace phalanx::protocol;

namespace {

constexpr int kIterations = 20000;  // fixed so that callgrind's total divides into a per-iteration count

Command glove5Command() {
  Command c;
  c.timeout_ms = 20;
  c.mode = Mode::kSetpoint;
  c.channel_count = 5;
  for (int i = 0; i < 5; ++i) {
    c.setpoint[i] = 0.5f * static_cast<float>(i);
    c.gain_scale_permille[i] = 1000;
  }
  return c;
}

Telemetry glove5Telemetry() {
  Telemetry t;
  t.mode = Mode::kSetpoint;
  for (int i = 0; i < 25; ++i) t.sample[i] = static_cast<int16_t>(i * 1311 - 16000);
  return t;
}

// Host side of one tick: send the command and receive the telemetry. The device end is a bare descriptor (its
// frames pre-encoded, written and drained with plain system calls) so that only the host's CanLink is measured.
void hostTick(benchmark::State& state, can::Flavor flavor) {
  int fds[2];
  if (socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK | SOCK_CLOEXEC, 0, fds) != 0) std::abort();
  linux_hal::CanLink host;
  linux_hal::CanLink::Options o;
  o.flavor = flavor;
  o.role = can::Role::kHost;
  host.adopt(fds[0], o);
  host.setDevice(DeviceType::kGlove5, 1000);
  can::Mapper dev(flavor, can::Role::kDevice, 1);
  dev.setDevice(DeviceType::kGlove5, 1000);
  uint8_t tp[Telemetry::kWireSize];
  encodePayload(glove5Telemetry(), tp);
  can::CanFrame tel[can::kMaxFramesPerMessage];
  can::EncodeStatus st;
  const size_t nt = dev.encode(static_cast<uint8_t>(MsgId::kTelemetry), tp, sizeof tp, tel, st);
  canfd_frame raw[can::kMaxFramesPerMessage] = {};
  for (size_t i = 0; i < nt; ++i) {
    raw[i].can_id = tel[i].id;
    raw[i].len = tel[i].len;
    std::memcpy(raw[i].data, tel[i].data, tel[i].len);
  }
  const size_t mtu = can::isFd(flavor) ? CANFD_MTU : CAN_MTU;
  Command c = glove5Command();
  uint8_t cp[Command::kWireSize];
  uint8_t id;
  uint8_t buf[64];
  size_t len;
  canfd_frame sink;
  for (auto _ : state) {
    for (size_t i = 0; i < nt; ++i) {
      if (write(fds[1], &raw[i], mtu) != static_cast<ssize_t>(mtu)) std::abort();
    }
    ++c.seq;
    encodePayload(c, cp);
    benchmark::DoNotOptimize(host.send(static_cast<uint8_t>(MsgId::kCommand), cp, sizeof cp));
    if (!host.receive(id, buf, len)) std::abort();
    while (read(fds[1], &sink, sizeof sink) > 0) {
    }
  }
  close(fds[1]);
}

void BM_HostTickFd(benchmark::State& state) { hostTick(state, can::Flavor::kFd); }
void BM_HostTickClassic(benchmark::State& state) { hostTick(state, can::Flavor::kClassic); }
void BM_HostTickFdCompact(benchmark::State& state) { hostTick(state, can::Flavor::kFdCompact); }
BENCHMARK(BM_HostTickFd)->Iterations(kIterations);
BENCHMARK(BM_HostTickClassic)->Iterations(kIterations);
BENCHMARK(BM_HostTickFdCompact)->Iterations(kIterations);

// The mapping alone (no system calls): command encode on the host + telemetry decode on the host.
void mapping(benchmark::State& state, can::Flavor flavor) {
  can::Mapper host(flavor, can::Role::kHost, 1), dev(flavor, can::Role::kDevice, 1);
  host.setDevice(DeviceType::kGlove5, 1000);
  dev.setDevice(DeviceType::kGlove5, 1000);
  uint8_t cp[Command::kWireSize];
  uint8_t tp[Telemetry::kWireSize];
  encodePayload(glove5Command(), cp);
  encodePayload(glove5Telemetry(), tp);
  can::CanFrame tel[can::kMaxFramesPerMessage];
  can::CanFrame out[can::kMaxFramesPerMessage];
  can::EncodeStatus st;
  const size_t nt = dev.encode(static_cast<uint8_t>(MsgId::kTelemetry), tp, sizeof tp, tel, st);
  uint8_t id;
  uint8_t buf[64];
  size_t len;
  for (auto _ : state) {
    benchmark::DoNotOptimize(host.encode(static_cast<uint8_t>(MsgId::kCommand), cp, sizeof cp, out, st));
    for (size_t i = 0; i < nt; ++i) benchmark::DoNotOptimize(host.decode(tel[i], id, buf, len));
    benchmark::ClobberMemory();
  }
}
void BM_MappingFd(benchmark::State& state) { mapping(state, can::Flavor::kFd); }
void BM_MappingClassic(benchmark::State& state) { mapping(state, can::Flavor::kClassic); }
void BM_MappingFdCompact(benchmark::State& state) { mapping(state, can::Flavor::kFdCompact); }
BENCHMARK(BM_MappingFd)->Iterations(kIterations);
BENCHMARK(BM_MappingClassic)->Iterations(kIterations);
BENCHMARK(BM_MappingFdCompact)->Iterations(kIterations);

}  // namespace
