// Press one glove fingertip of a device on another machine, addressed by the name its daemon announces
// (libphalanx's network part, phalanx/network.hpp; docs/sdk.md §"Devices on the network").
//
//   remote_press --list [--domain N] [--interface IF]
//   remote_press --device NAME [--host HOST] [--finger 1] [--force 0.75] [--seconds 1] [--rate-hz 200]
//                [--domain N] [--interface IF] [--discovery-s 2]
//
// --list prints every announced device. Otherwise the glove's pad-force setpoint of --finger is --force N (raw
// setpoints, the other fingers 0) at --rate-hz for --seconds, then the device is released; the joint states
// received meanwhile are counted. Prints one JSON line. Exit 0, 2 bad arguments, 3 the device could not be
// addressed (the reason on stderr), 4 a command could not be sent.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include "phalanx/network.hpp"

namespace {

struct Args {
  std::string device, host;
  bool list = false;
  int finger = 1;
  double force_N = 0.75, seconds = 1.0, rate_hz = 200.0;
  phalanx::NetworkOptions net;
};

bool number(const char* v, double lo, double hi, double& out) {
  char* end = nullptr;
  const double x = std::strtod(v, &end);
  if (end == v || *end != '\0' || !(x >= lo && x <= hi)) return false;
  out = x;
  return true;
}

bool parse(int argc, char** argv, Args& a) {
  for (int i = 1; i < argc; ++i) {
    const std::string key = argv[i];
    if (key == "--list") {
      a.list = true;
      continue;
    }
    if (i + 1 >= argc) {
      std::fprintf(stderr, "remote_press: %s needs a value\n", key.c_str());
      return false;
    }
    const char* v = argv[++i];
    double x = 0.0;
    bool ok = true;
    if (key == "--device") a.device = v;
    else if (key == "--host") a.net.host = v;
    else if (key == "--interface") a.net.interface = v;
    else if (key == "--domain") ok = number(v, 0, 232, x), a.net.domain = static_cast<unsigned>(x);
    else if (key == "--finger") ok = number(v, 0, 4, x), a.finger = static_cast<int>(x);
    else if (key == "--force") ok = number(v, -10, 10, a.force_N);
    else if (key == "--seconds") ok = number(v, 0.01, 3600, a.seconds);
    else if (key == "--rate-hz") ok = number(v, 1, 1000, a.rate_hz);
    else if (key == "--discovery-s") ok = number(v, 0.1, 60, a.net.discovery_s);
    else {
      std::fprintf(stderr, "remote_press: unknown option %s\n", key.c_str());
      return false;
    }
    if (!ok) {
      std::fprintf(stderr, "remote_press: %s: bad value '%s'\n", key.c_str(), v);
      return false;
    }
  }
  if (!a.list && a.device.empty()) {
    std::fprintf(stderr, "remote_press: give --device NAME or --list\n");
    return false;
  }
  return true;
}

int list(const Args& a) {
  for (const phalanx::NetworkDevice& d : phalanx::listNetworkDevices(a.net)) {
    std::printf("%s %s %s %.0f Hz commands %s: %s\n", d.host.c_str(), d.name.c_str(), d.type.c_str(), d.rate_hz,
                d.commands ? "on" : "off", d.state.c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  if (!parse(argc, argv, a)) return 2;
  try {
    if (a.list) return list(a);
    phalanx::RemoteDevice dev(a.device, a.net);
    if (dev.device().type != "glove5") {
      std::fprintf(stderr, "remote_press: %s is a %s, not a glove5\n", a.device.c_str(), dev.device().type.c_str());
      return 3;
    }
    phalanx::Command cmd;
    cmd.setpoint[static_cast<size_t>(a.finger)] = static_cast<float>(a.force_N);
    const auto period = std::chrono::duration<double>(1.0 / a.rate_hz);
    const long n = static_cast<long>(a.seconds * a.rate_hz + 0.5);
    phalanx::RemoteJoints joints;
    auto next = std::chrono::steady_clock::now();
    for (long i = 0; i < n; ++i) {
      if (!dev.send(cmd)) {
        std::fprintf(stderr, "remote_press: %s\n", dev.lastError().c_str());
        return 4;
      }
      while (dev.waitJoints(joints, 0)) {
      }
      next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
      std::this_thread::sleep_until(next);
    }
    dev.release();
    std::printf("{\"device\": \"%s\", \"host\": \"%s\", \"type\": \"%s\", \"commands_sent\": %ld, \"joint_states\": %llu}\n",
                dev.device().name.c_str(), dev.device().host.c_str(), dev.device().type.c_str(), n,
                static_cast<unsigned long long>(joints.received));
    return 0;
  } catch (const phalanx::Error& e) {
    std::fprintf(stderr, "remote_press: %s\n", e.what());
    return 3;
  }
}
