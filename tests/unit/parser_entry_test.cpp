// The in-memory entry points the fuzz targets drive (docs/fuzzing.md) behave as the file/socket paths do:
// geometry from text, the dashboard's routes served from memory, the Modbus server on one connected socket, the
// client channel's ConnectRequest checks.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstring>
#include <fstream>
#include <sstream>

#include "phalanx/host/api/dashboard.h"
#include "phalanx/host/client/client_port.h"
#include "phalanx/host/design/glove_design.h"
#include "phalanx/host/design/pen_geometry.h"
#include "phalanx/host/modbus/server.h"

using namespace phalanx;
using namespace phalanx::host;

namespace {

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST(ParserEntry, GeometryFromTextMatchesTheFile) {
  const std::string pen_path = std::string(PHALANX_SOURCE_DIR) + "/docs/design/pen-geometry-20cm-prototype.yaml";
  pen::Geometry<double> a{}, b{};
  ASSERT_EQ(design::loadPenGeometryYaml(pen_path, a), "");
  ASSERT_EQ(design::loadPenGeometryText(slurp(pen_path), pen_path, b), "");
  EXPECT_EQ(a.l1_m, b.l1_m);
  EXPECT_EQ(a.home_z_m, b.home_z_m);
  const std::string glove_path = std::string(PHALANX_SOURCE_DIR) + "/docs/design/glove-index-optimum.yaml";
  design::GloveModel g1{}, g2{};
  ASSERT_EQ(design::loadGloveGeometryYaml(glove_path, g1), "");
  ASSERT_EQ(design::loadGloveGeometryText(slurp(glove_path), glove_path, g2), "");
  EXPECT_EQ(g1.mech.l1_m, g2.mech.l1_m);
  EXPECT_EQ(g1.finger.p3_m, g2.finger.p3_m);
  EXPECT_NE(design::loadPenGeometryYaml("/nonexistent.yaml", a).find("cannot read"), std::string::npos);
  EXPECT_NE(design::loadGloveGeometryYaml("/nonexistent.yaml", g1).find("cannot read"), std::string::npos);
}

TEST(ParserEntry, DashboardRoutesServedFromMemoryApplyTheListenersChecks) {
  int calls = 0;
  api::DashboardOptions opt;
  opt.enabled = true;
  opt.address = "127.0.0.1";
  api::Dashboard d(opt, [&calls](const std::string& line) {
    ++calls;
    return nlohmann::json{{"ok", true}, {"echo", line}};
  });
  const std::string body = R"({"cmd":"status"})";
  auto post = [&](const std::string& host, const std::string& token) {
    return d.serveInMemory("POST /api/request HTTP/1.1\r\nHost: " + host + "\r\nX-Phalanx-Token: " + token +
                               "\r\nContent-Length: " + std::to_string(body.size()) + "\r\n\r\n" + body,
                           "c0ffee");
  };
  EXPECT_EQ(post("127.0.0.1:0", "wrong").rfind("HTTP/1.1 401", 0), 0u);
  EXPECT_EQ(post("evil.example:0", "c0ffee").rfind("HTTP/1.1 421", 0), 0u);
  EXPECT_EQ(calls, 0);  // refused requests never reach the handler
  const std::string ok = post("127.0.0.1:0", "c0ffee");
  EXPECT_EQ(ok.rfind("HTTP/1.1 200", 0), 0u) << ok;
  EXPECT_NE(ok.find(R"(\"cmd\":\"status\")"), std::string::npos) << ok;
  EXPECT_EQ(calls, 1);
}

TEST(ParserEntry, ModbusServerServesOneConnectedSocket) {
  modbus::ServerOptions o;
  o.writes_enabled = true;
  const protocol::DeviceLayout& l = protocol::kSeaFingerLayout;
  modbus::Server server(o, {l.setpoint_count, l.setpoint_limit});
  int sv[2];
  ASSERT_EQ(::socketpair(AF_UNIX, SOCK_STREAM, 0, sv), 0);
  // FC 06: control source (holding 0) := 1 (Modbus); then FC 06 to an address beyond the map.
  const uint8_t req[] = {0, 1, 0, 0, 0, 6, 1, 6, 0, 0, 0, 1, 0, 2, 0, 0, 0, 6, 1, 6, 0x7F, 0, 0, 1};
  ASSERT_EQ(::write(sv[0], req, sizeof req), static_cast<ssize_t>(sizeof req));
  ::shutdown(sv[0], SHUT_WR);
  EXPECT_EQ(server.serveConnection(sv[1]), "");
  uint8_t resp[64];
  const ssize_t n = ::read(sv[0], resp, sizeof resp);
  ::close(sv[0]);
  ::close(sv[1]);
  ASSERT_EQ(n, 12 + 9);  // the echo of the accepted write, then an exception
  EXPECT_EQ(std::memcmp(resp, req, 12), 0);
  EXPECT_EQ(resp[12 + 7], 0x86);
  EXPECT_EQ(resp[12 + 8], 2);  // illegal data address
  modbus::RemoteCommand cmd;
  ASSERT_TRUE(server.latestCommand(cmd));
  EXPECT_EQ(cmd.source, modbus::ControlSource::kModbus);
  EXPECT_EQ(server.stats().requests.load(), 2u);
}

TEST(ParserEntry, ConnectRequestChecks) {
  client_wire::ConnectRequest r;
  std::string why;
  EXPECT_EQ(client::checkConnectRequest(r, sizeof r, 1000, false, why), client_wire::ConnectStatus::kOk);
  EXPECT_EQ(client::checkConnectRequest(r, sizeof r - 1, 1000, false, why), client_wire::ConnectStatus::kBadRequest);
  EXPECT_EQ(client::checkConnectRequest(r, sizeof r, 1000, true, why), client_wire::ConnectStatus::kBusy);
  r.deadline_ms = 1;
  EXPECT_EQ(client::checkConnectRequest(r, sizeof r, 1000, false, why), client_wire::ConnectStatus::kBadRequest);
  r.deadline_ms = 2;
  EXPECT_EQ(client::checkConnectRequest(r, sizeof r, 1000, false, why), client_wire::ConnectStatus::kOk);
  EXPECT_EQ(client::checkConnectRequest(r, sizeof r, 333, false, why), client_wire::ConnectStatus::kBadRequest);
  r.deadline_ms = 1001;
  EXPECT_EQ(client::checkConnectRequest(r, sizeof r, 1000, false, why), client_wire::ConnectStatus::kBadRequest);
  r.deadline_ms = 20;
  r.fallback = static_cast<client_wire::Fallback>(2);
  EXPECT_EQ(client::checkConnectRequest(r, sizeof r, 1000, false, why), client_wire::ConnectStatus::kBadRequest);
  EXPECT_NE(why.find("fallback"), std::string::npos);
  r.fallback = client_wire::Fallback::kSafe;
  r.version = client_wire::kVersion + 1;
  EXPECT_EQ(client::checkConnectRequest(r, sizeof r, 1000, false, why), client_wire::ConnectStatus::kVersionMismatch);
}

TEST(ParserEntry, GeometryFilesWithScalarsOrListsWhereMappingsBelongAreRefusedNotThrown) {
  // Found with the geometry fuzz target: yaml-cpp throws on operator[] of a scalar and on converting a list key
  // to a string, and these escaped the loaders (phalanxd ended with an uncaught exception on such a file).
  design::GloveModel g{};
  for (const char* text : {"x", "glove_finger_geometry: 3", "glove_finger_geometry: {finger: 1, mechanism: {}}",
                           "glove_finger_geometry: {finger: {}, mechanism: [1]}"}) {
    std::string err;
    EXPECT_NO_THROW(err = design::loadGloveGeometryText(text, "g.yaml", g)) << text;
    EXPECT_EQ(err.rfind("g.yaml: ", 0), 0u) << text << " → " << err;
  }
  pen::Geometry<double> p{};
  for (const char* text : {"pen_geometry: {? [a, b]: 1}", "x", "pen_geometry: 3"}) {
    std::string err;
    EXPECT_NO_THROW(err = design::loadPenGeometryText(text, "p.yaml", p)) << text;
    EXPECT_EQ(err.rfind("p.yaml: ", 0), 0u) << text << " → " << err;
  }
  // A non-finite l_p_mm was accepted (every other length was checked).
  const std::string glove_path = std::string(PHALANX_SOURCE_DIR) + "/docs/design/glove-index-optimum.yaml";
  std::string text = slurp(glove_path);
  const auto at = text.find("l_p_mm:");
  ASSERT_NE(at, std::string::npos);
  text = text.substr(0, at) + "l_p_mm: .nan" + text.substr(text.find('\n', at));
  EXPECT_NE(design::loadGloveGeometryText(text, "g.yaml", g).find("l_p_mm"), std::string::npos);
}
