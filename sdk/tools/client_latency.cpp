// Latency benchmark client (docs/sdk.md "Benchmarks"; printed, not gated): a C++ servo-callback client on the pen
// that renders a gentle spring, and the figures from the daemon's own time stamps:
//  - client: telemetry arrival (state.telemetry_rx_ns of the state a command was computed from) → the wake-up of
//    the daemon cycle that sent that command (the state whose command_seq_used is it);
//  - built-in: the same daemon cycle's wake-up minus the arrival of the telemetry it computed from (what the
//    built-in controller's command waits on the same clock), over the same run;
//  - reaction: the daemon cycle's wake-up → this callback running on that cycle's state (CLOCK_MONOTONIC, the
//    daemon's clock); a reaction later than one period is a cycle the client could not answer in time.
// Both exclude the few µs from the wake-up to the send, equal for both.
//   phalanx_client_latency SOCKET SECONDS [DEADLINE_MS=250]
#include <algorithm>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "phalanx/client.hpp"

namespace {

void print(const char* what, std::vector<double>& v) {
  if (v.empty()) {
    std::printf("%s: no samples\n", what);
    return;
  }
  std::sort(v.begin(), v.end());
  const auto q = [&v](double p) { return v[static_cast<size_t>(p * static_cast<double>(v.size() - 1))]; };
  std::printf("%s: n=%zu p50=%.1f us p99=%.1f us max=%.1f us\n", what, v.size(), q(0.5), q(0.99), v.back());
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3 && argc != 4) {
    std::fprintf(stderr, "usage: phalanx_client_latency SOCKET SECONDS [DEADLINE_MS=250]\n");
    return 2;
  }
  const double seconds = std::atof(argv[2]);
  try {
    const unsigned deadline_ms = argc == 4 ? static_cast<unsigned>(std::atoi(argv[3])) : 250u;
    phalanx::Client client({argv[1], deadline_ms, phalanx::Fallback::kSafe});
    const unsigned rate = client.device().rate_hz;
    const size_t n = static_cast<size_t>(seconds * rate) + 16;
    std::vector<uint64_t> rx_of_seq(n + 2, 0);  // preallocated: command k (seq k) was computed from this arrival
    std::vector<double> client_us, builtin_us, reaction_us;
    client_us.reserve(n);
    builtin_us.reserve(n);
    reaction_us.reserve(n);
    uint32_t seq = 0;
    uint64_t first_cycle = 0, last_cycle = 0, skipped = 0;
    float c0[3] = {0, 0, 0};
    bool have_c0 = false;
    const int rc = client.runServo([&](const phalanx::State& s, phalanx::Command& cmd) {
      timespec now{};
      clock_gettime(CLOCK_MONOTONIC, &now);
      const uint64_t now_ns = static_cast<uint64_t>(now.tv_sec) * 1000000000ull + static_cast<uint64_t>(now.tv_nsec);
      if (now_ns >= s.daemon_time_ns) reaction_us.push_back(static_cast<double>(now_ns - s.daemon_time_ns) * 1e-3);
      if (first_cycle != 0 && s.cycle > last_cycle + 1) skipped += s.cycle - last_cycle - 1;
      if (first_cycle == 0) first_cycle = s.cycle;
      last_cycle = s.cycle;
      if (s.command_seq_used != 0 && s.command_seq_used <= seq && rx_of_seq[s.command_seq_used] != 0) {
        client_us.push_back(static_cast<double>(s.daemon_time_ns - rx_of_seq[s.command_seq_used]) * 1e-3);
      }
      if (s.telemetry_rx_ns != 0 && s.daemon_time_ns >= s.telemetry_rx_ns) {
        builtin_us.push_back(static_cast<double>(s.daemon_time_ns - s.telemetry_rx_ns) * 1e-3);
      }
      if (!have_c0 && s.pen.valid) {
        for (int i = 0; i < 3; ++i) c0[i] = s.pen.centre_m[i];
        have_c0 = true;
      }
      std::array<double, 3> f{};
      for (int i = 0; i < 3; ++i) f[i] = have_c0 ? 100.0 * static_cast<double>(c0[i] - s.pen.centre_m[i]) : 0.0;
      cmd.penWrench(f, {0, 0, 0});
      ++seq;
      if (seq < rx_of_seq.size()) rx_of_seq[seq] = s.telemetry_rx_ns;
      return seq + 1 < rx_of_seq.size() && static_cast<double>(s.cycle - first_cycle) < seconds * rate;
    });
    phalanx::State last{};
    client.getState(last);
    std::printf("C++ callback client: %u commands over %llu daemon cycles, achieved %.1f Hz, rc %d\n", seq,
                static_cast<unsigned long long>(last_cycle - first_cycle + 1), static_cast<double>(last.achieved_rate_hz), rc);
    print("client (telemetry arrival -> the daemon cycle that sent its command)", client_us);
    print("built-in (telemetry arrival -> the daemon cycle that computed from it)", builtin_us);
    const double period_us = 1e6 / rate;
    const auto late = std::count_if(reaction_us.begin(), reaction_us.end(), [&](double r) { return r > period_us; });
    print("reaction (daemon cycle wake-up -> this callback on its state)", reaction_us);
    std::printf("reactions later than one period: %lld; states never seen (the client woke after the next one was "
                "written): %llu\n", static_cast<long long>(late), static_cast<unsigned long long>(skipped));
    return 0;
  } catch (const phalanx::Error& e) {
    std::fprintf(stderr, "phalanx_client_latency: %s\n", e.what());
    return 3;
  }
}
