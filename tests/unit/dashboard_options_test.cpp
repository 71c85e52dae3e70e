// Dashboard options (command line and config file) and the dashboard's sampler, in process with a fake request
// handler (the HTTP side is tested end to end in tests/integration/dashboard_test.cpp).
#include <gtest/gtest.h>

#include <atomic>
#include <cstdio>
#include <chrono>
#include <thread>

#include "../support/http_client.h"
#include "phalanx/host/api/dashboard.h"
#include "phalanx/host/config.h"

using namespace phalanx::host;
using phalanx::host::api::DashboardOptions;

TEST(DashboardOptions, SpecsAreParsedAndValidated) {
  DashboardOptions o;
  EXPECT_EQ(api::parseDashboardSpec("127.0.0.1:8080", o), "");
  EXPECT_TRUE(o.enabled);
  EXPECT_EQ(o.address, "127.0.0.1");
  EXPECT_EQ(o.port, 8080);
  EXPECT_EQ(api::parseDashboardSpec("[::1]:0", o), "");
  EXPECT_EQ(o.address, "::1");
  EXPECT_EQ(o.port, 0);
  DashboardOptions before = o;
  for (const char* bad : {"8080", "127.0.0.1", "127.0.0.1:", "127.0.0.1:65536", "127.0.0.1:80a", "localhost:8080",
                          "0.0.0.0:8080", "192.168.1.2:8080", "[::]:8080", "[::1]8080", "::1:8080"}) {
    EXPECT_NE(api::parseDashboardSpec(bad, o), "") << bad;
    EXPECT_EQ(o.address, before.address) << "a refused spec changes nothing: " << bad;
  }
  EXPECT_NE(api::parseDashboardSpec("0.0.0.0:8080", o).find("allow_remote"), std::string::npos);
  EXPECT_TRUE(api::isLoopbackAddress("127.5.6.7"));
  EXPECT_FALSE(api::isLoopbackAddress("10.0.0.1"));
  o.allow_remote = true;
  EXPECT_EQ(api::parseDashboardSpec("0.0.0.0:8080", o), "");
}

TEST(DashboardOptions, ConfigFileKeyIsValidated) {
  RunOptions opt;
  EXPECT_EQ(loadConfigText("dashboard: {listen: '127.0.0.1:9000'}\n", "c.yaml", opt), "");
  EXPECT_TRUE(opt.dashboard.enabled);
  EXPECT_EQ(opt.dashboard.port, 9000);
  RunOptions off;
  EXPECT_EQ(loadConfigText("dashboard: {listen: '127.0.0.1:9000', enabled: false}\n", "c.yaml", off), "");
  EXPECT_FALSE(off.dashboard.enabled);
  RunOptions remote;
  EXPECT_NE(loadConfigText("dashboard: {listen: '10.1.2.3:9000'}\n", "c.yaml", remote), "");
  EXPECT_FALSE(remote.dashboard.enabled);
  EXPECT_EQ(loadConfigText("dashboard: {listen: '10.1.2.3:9000', allow_remote: true}\n", "c.yaml", remote), "");
  EXPECT_TRUE(remote.dashboard.enabled);
  RunOptions typo;
  const std::string err = loadConfigText("dashboard: {listen: '127.0.0.1:9000', port: 1}\n", "c.yaml", typo);
  EXPECT_NE(err.find("dashboard.port"), std::string::npos) << err;
}

// The sampler keeps only new loop snapshots (by session time), restarts the plots for a new session, and never
// holds more than its ring.
TEST(DashboardSampler, KeepsNewSnapshotsOfTheRunningSession) {
  std::atomic<int> calls{0};
  std::atomic<double> t_s{1.0};
  std::atomic<int> session{1};
  auto handler = [&](const std::string& line) {
    ++calls;
    EXPECT_EQ(line, "{\"cmd\":\"status\"}");
    nlohmann::json s{{"phase", "running"}, {"device", "sea_finger"}, {"record", "r" + std::to_string(session.load())},
                     {"t_s", t_s.load()}, {"device_mode", "transparent"}, {"faults", "none"}, {"estop", false},
                     {"effort_unit", "N·m"},
                     {"channels", {{"mcp", {{"q_deg", 10.0}, {"target_deg", nullptr}, {"effort_measured", 0.01},
                                            {"effort_command", 0.0}, {"effort_max", 0.3}}}}},
                     {"joints", {{"mcp", {{"flexion_deg", 10.0}}}}}};
    return nlohmann::json{{"ok", true}, {"result", {{"session_running", true}, {"session", s}}}};
  };
  DashboardOptions o;
  o.enabled = true;
  o.port = 0;
  api::Dashboard d(o, handler);
  ASSERT_EQ(d.start(), "");
  EXPECT_GT(d.port(), 0);
  EXPECT_EQ(d.token().size(), 32u);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  nlohmann::json a = d.samplesAfter(0);
  EXPECT_EQ(a["samples"].size(), 1u) << "the same snapshot is kept once";
  EXPECT_EQ(a["status"]["device_mode"], "transparent");
  EXPECT_EQ(a["meta"]["channels"], nlohmann::json::array({"mcp"}));
  for (int i = 0; i < 10; ++i) {
    t_s = t_s + 0.02;
    std::this_thread::sleep_for(std::chrono::milliseconds(40));
  }
  a = d.samplesAfter(0);
  EXPECT_GE(a["samples"].size(), 5u);
  const uint64_t last = a["last_seq"].get<uint64_t>();
  EXPECT_EQ(d.samplesAfter(last)["samples"].size(), 0u);
  EXPECT_TRUE(a["samples"].back()["tg"][0].is_null());
  session = 2;  // a new session: the old samples are dropped
  t_s = 0.5;
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  a = d.samplesAfter(0);
  EXPECT_EQ(a["samples"].size(), 1u);
  EXPECT_EQ(a["meta"]["session"], "r2|sea_finger");
  d.stop();
  const int n = calls.load();
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(calls.load(), n) << "stopped means stopped";
  EXPECT_GT(n, 10);
}

namespace {

nlohmann::json statusAt(double t_s) {
  nlohmann::json s{{"phase", "replay"}, {"device", "sea_finger"}, {"record", "r.mcap"}, {"t_s", t_s},
                   {"replay", {{"file", "r.mcap"}, {"speed", 4.0}}},
                   {"channels", {{"mcp", {{"q_deg", t_s}, {"effort_measured", 0.01}}}}},
                   {"joints", {{"mcp", {{"flexion_deg", t_s}}}}}};
  return {{"ok", true}, {"result", {{"session_running", true}, {"session", s}}}};
}

}  // namespace

// Published sampling (a replay): every published snapshot with a newer session time is one sample, whatever the
// rate; the handler is never polled; deliveredSeq() says how far a client has fetched without a gap.
TEST(DashboardSampler, PublishedSnapshotsAreEachOneSample) {
  std::atomic<int> calls{0};
  DashboardOptions o;
  o.enabled = true;
  o.port = 0;
  api::Dashboard d(o, [&](const std::string&) { ++calls; return statusAt(0.0); }, api::Dashboard::Sampling::kPublished);
  ASSERT_EQ(d.start(), "");
  for (int i = 0; i < 1000; ++i) d.publish(statusAt(0.02 * i));  // far faster than 50 Hz
  d.publish(statusAt(0.02 * 999));  // the same session time again: no new sample
  EXPECT_EQ(d.lastSeq(), 1000u);
  EXPECT_EQ(d.deliveredSeq(), 0u);
  nlohmann::json a = d.samplesAfter(0);
  EXPECT_EQ(a["samples"].size(), api::Dashboard::kMaxSamplesPerAnswer);
  EXPECT_EQ(a["status"]["replay"]["speed"], 4.0);
  EXPECT_EQ(d.deliveredSeq(), 500u);
  a = d.samplesAfter(500);
  EXPECT_EQ(a["samples"].size(), 500u);
  EXPECT_EQ(a["samples"].back()["t"], 0.02 * 999);
  EXPECT_EQ(d.deliveredSeq(), 1000u);
  d.stop();
  EXPECT_EQ(calls.load(), 0) << "a published dashboard never polls its handler for status";
}

// Dashboard::stop() ends open connections at once: an idle keep-alive one, one with half a request sent, and
// one polling every 20 ms as a page does (before the fix stop() waited for each of them: the keep-alive timeout,
// the 5 s read timeout, and up to 200 requests of the polling one).
TEST(DashboardStop, EndsOpenKeepAliveConnectionsPromptly) {
  DashboardOptions o;
  o.enabled = true;
  o.port = 0;
  api::Dashboard d(o, [](const std::string&) { return statusAt(1.0); });
  ASSERT_EQ(d.start(), "");
  const std::string host = "127.0.0.1:" + std::to_string(d.port());
  const std::string tok = "X-Phalanx-Token: " + d.token() + "\r\n";
  phalanx::test::KeepAlive idle(d.port()), half(d.port()), polling(d.port());
  ASSERT_EQ(idle.request("GET", "/api/samples", host, tok).status, 200);
  ASSERT_TRUE(half.send("GET /api/samples HTTP/1.1\r\nHost: " + host + "\r\n"));
  std::atomic<bool> done{false};
  std::atomic<int> polls{0};
  std::thread poller([&] {
    while (!done && polling.request("GET", "/api/samples", host, tok).status == 200) {
      ++polls;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  });
  for (int i = 0; i < 500 && polls < 5; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_GE(polls.load(), 5);
  const auto t0 = std::chrono::steady_clock::now();
  d.stop();
  const double stop_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  done = true;
  poller.join();
  // 1.5 s: well above the ~0.1 s it takes (one keep-alive poll step), well below the 2 s keep-alive timeout and
  // the 5 s read timeout the old stop() waited for.
  EXPECT_LT(stop_s, 1.5) << "stop() took " << stop_s << " s";
  EXPECT_TRUE(idle.closedByServer(1000));
  EXPECT_TRUE(half.closedByServer(1000));
  std::printf("Dashboard::stop() with 3 open keep-alive connections: %.3f s\n", stop_s);
}
