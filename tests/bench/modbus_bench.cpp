// What the Modbus server costs the 1 kHz loop per cycle: LoopPort::overrideCommand + LoopPort::publish (one
// TripleBuffer read and one publish of a ~200-byte snapshot), alone and while 16 clients poll the server.
#include <arpa/inet.h>
#include <benchmark/benchmark.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <thread>
#include <vector>

#include "phalanx/host/modbus/server.h"
#include "phalanx/linux/realtime.h"
#include "phalanx/protocol/devices.h"

namespace mb = phalanx::host::modbus;

namespace {

void cycle(benchmark::State& state, int clients) {
  mb::ServerOptions o;
  o.port = 0;
  o.writes_enabled = true;
  mb::Server server(o, mb::WriteLimits{2, 0.3f});
  if (!server.start().empty()) {
    state.SkipWithError("server did not start");
    return;
  }
  mb::LoopPort port(server, o, 2, 13, 2);
  std::atomic<bool> stop{false};
  std::vector<std::thread> pollers;
  for (int c = 0; c < clients; ++c) {
    pollers.emplace_back([&] {
      const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
      sockaddr_in a{};
      a.sin_family = AF_INET;
      a.sin_port = htons(static_cast<uint16_t>(server.port()));
      a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
      if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) return;
      // Read all 112 input registers every 10 ms (100 Hz), like tools/modbus-load.sh's mbpoll clients.
      const uint8_t req[12] = {0, 1, 0, 0, 0, 6, 1, 4, 0, 0, 0, 112};
      uint8_t buf[300];
      while (!stop) {
        if (::write(fd, req, sizeof req) != static_cast<ssize_t>(sizeof req)) break;
        if (::read(fd, buf, sizeof buf) <= 0) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
      ::close(fd);
    });
  }
  phalanx::host::TelemetryFrame tel;
  phalanx::protocol::Command cmd;
  uint64_t k = 0;
  for (auto _ : state) {
    const uint64_t now = phalanx::linux_hal::monotonicNs();
    port.overrideCommand(cmd, now);
    tel.seq = static_cast<uint16_t>(k);
    port.publish(tel, cmd, ++k, 0, 12.0, 30.0, now, 0, mb::LoopState::kRunning);
    benchmark::DoNotOptimize(cmd);
  }
  stop = true;
  for (auto& t : pollers) t.join();
  state.counters["requests_served"] = static_cast<double>(server.stats().requests.load());
}

void BM_LoopPortCycle_NoClients(benchmark::State& s) { cycle(s, 0); }
void BM_LoopPortCycle_16ClientsAt100Hz(benchmark::State& s) { cycle(s, 16); }

}  // namespace

BENCHMARK(BM_LoopPortCycle_NoClients)->Repetitions(5)->ReportAggregatesOnly(true)->MinTime(0.5);
BENCHMARK(BM_LoopPortCycle_16ClientsAt100Hz)->Repetitions(5)->ReportAggregatesOnly(true)->MinTime(0.5);
