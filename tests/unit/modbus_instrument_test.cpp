// Reference instrument over Modbus: register decoding, TCP and RTU polling against the simulated amplifier,
// timeouts and stale-data detection.
#include <gtest/gtest.h>
#include <time.h>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cmath>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "phalanx/host/modbus/instrument.h"
#include "phalanx/linux/realtime.h"

namespace mb = phalanx::host::modbus;
using phalanx::linux_hal::monotonicNs;

namespace {

/// Poll latest() until pred holds or timeout_s passes; returns the last reading.
template <class Pred>
mb::InstrumentReading waitFor(mb::InstrumentClient& c, Pred pred, double timeout_s = 3.0) {
  const uint64_t end = monotonicNs() + static_cast<uint64_t>(timeout_s * 1e9);
  mb::InstrumentReading r;
  while (monotonicNs() < end) {
    r = c.latest(monotonicNs());
    if (pred(r)) return r;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return r;
}

mb::InstrumentConfig loadCellMap() {
  mb::InstrumentConfig c;
  c.type = "int32";
  c.address = 10;
  c.scale = 1e-5;  // N·m per count
  c.offset = 0.002;
  c.poll_hz = 200;
  c.timeout_ms = 40;
  c.stale_ms = 100;
  return c;
}

}  // namespace

TEST(ModbusInstrument, EveryRegisterTypeRoundTripsThroughScaleAndOffset) {
  for (const char* type : {"int16", "uint16", "int32", "uint32", "float32"}) {
    for (const char* order : {"big", "little"}) {
      mb::InstrumentConfig c;
      c.type = type;
      c.word_order = order;
      c.scale = 1e-3;
      c.offset = std::string(type).rfind("uint", 0) == 0 ? -1.0 : 0.5;
      uint16_t r[2] = {};
      mb::encodeInstrument(c, 1.2345, r);
      EXPECT_NEAR(mb::decodeInstrument(c, r), 1.2345, 0.6e-3) << type << " " << order;
    }
  }
  mb::InstrumentConfig c;
  c.type = "int32";
  const uint16_t neg_big[2] = {0xFFFF, 0xFFFE};
  EXPECT_EQ(mb::decodeInstrument(c, neg_big), -2.0);
  c.word_order = "little";
  const uint16_t neg_little[2] = {0xFFFE, 0xFFFF};
  EXPECT_EQ(mb::decodeInstrument(c, neg_little), -2.0);
}

TEST(ModbusInstrument, ConfigurationErrorsNameTheKey) {
  mb::InstrumentConfig c;
  EXPECT_NE(mb::loadInstrumentConfig(YAML::Load("{port: 502, gain: 3}"), "instrument", c).find("instrument.gain: unknown key"),
            std::string::npos);
  EXPECT_NE(mb::loadInstrumentConfig(YAML::Load("{type: int64}"), "instrument", c).find("instrument.type"), std::string::npos);
  EXPECT_NE(mb::loadInstrumentConfig(YAML::Load("{scale: 0}"), "instrument", c).find("instrument.scale"), std::string::npos);
  EXPECT_NE(mb::loadInstrumentConfig(YAML::Load("{transport: rtu}"), "instrument", c).find("serial_device"), std::string::npos);
  EXPECT_EQ(mb::loadInstrumentConfig(YAML::Load("{type: float32, table: holding, scale: 1, poll_hz: 100}"), "instrument", c), "");
}

TEST(ModbusInstrument, TcpClientReadsTheSimulatedAmplifier) {
  const mb::InstrumentConfig map = loadCellMap();
  mb::SimInstrumentServer amp(map);
  ASSERT_EQ(amp.startTcp(), "");
  amp.set(-0.1234);
  mb::InstrumentConfig cfg = map;
  cfg.port = amp.port();
  mb::InstrumentClient client(cfg);
  ASSERT_EQ(client.start(), "");
  const auto r = waitFor(client, [](const mb::InstrumentReading& x) { return x.valid && !x.stale; });
  ASSERT_TRUE(r.valid) << r.last_error;
  EXPECT_NEAR(r.value, -0.1234, 1e-5);
  amp.set(0.25);
  const auto r2 = waitFor(client, [](const mb::InstrumentReading& x) { return std::fabs(x.value - 0.25) < 1e-4; });
  EXPECT_NEAR(r2.value, 0.25, 1e-5);
  EXPECT_FALSE(r2.stale);
}

TEST(ModbusInstrument, RtuClientReadsTheSimulatedAmplifierOverASerialLine) {
  mb::InstrumentConfig map = loadCellMap();
  map.type = "float32";
  map.scale = 1.0;
  map.offset = 0.0;
  map.table = "holding";
  map.unit_id = 7;
  mb::SimInstrumentServer amp(map);
  std::string tty;
  ASSERT_EQ(amp.startRtu(tty), "");
  amp.set(0.0625);
  mb::InstrumentConfig cfg = map;
  cfg.transport = "rtu";
  cfg.serial_device = tty;
  mb::InstrumentClient client(cfg);
  ASSERT_EQ(client.start(), "");
  const auto r = waitFor(client, [](const mb::InstrumentReading& x) { return x.valid && !x.stale; });
  ASSERT_TRUE(r.valid) << r.last_error;
  EXPECT_FLOAT_EQ(static_cast<float>(r.value), 0.0625f);
}

TEST(ModbusInstrument, HungAmplifierTimesOutAndItsDataGoesStaleThenRecovers) {
  const mb::InstrumentConfig map = loadCellMap();
  mb::SimInstrumentServer amp(map);
  ASSERT_EQ(amp.startTcp(), "");
  amp.set(0.1);
  mb::InstrumentConfig cfg = map;
  cfg.port = amp.port();
  mb::InstrumentClient client(cfg);
  ASSERT_EQ(client.start(), "");
  ASSERT_TRUE(waitFor(client, [](const mb::InstrumentReading& x) { return x.valid && !x.stale; }).valid);
  amp.setResponsive(false);
  const auto stale = waitFor(client, [](const mb::InstrumentReading& x) { return x.stale && x.timeouts > 0; });
  EXPECT_TRUE(stale.stale);
  EXPECT_GT(stale.timeouts, 0u) << stale.last_error;
  EXPECT_TRUE(stale.valid) << "the last good sample is kept, flagged stale";
  // latest() never waits on the instrument: it returns at once even while requests are timing out.
  const uint64_t t0 = monotonicNs();
  for (int i = 0; i < 1000; ++i) client.latest(monotonicNs());
  EXPECT_LT(monotonicNs() - t0, 20000000ull);
  amp.setResponsive(true);
  amp.set(0.2);
  const auto back = waitFor(client, [](const mb::InstrumentReading& x) { return !x.stale && std::fabs(x.value - 0.2) < 1e-4; });
  EXPECT_FALSE(back.stale) << back.last_error;
}

TEST(ModbusInstrument, NoAmplifierMeansNeverValidAndAlwaysStale) {
  mb::InstrumentConfig cfg = loadCellMap();
  cfg.port = 1;  // nothing listens on tcpmux here
  mb::InstrumentClient client(cfg);
  ASSERT_EQ(client.start(), "");
  const auto r = waitFor(client, [](const mb::InstrumentReading& x) { return x.errors > 0; });
  EXPECT_FALSE(r.valid);
  EXPECT_TRUE(r.stale);
  EXPECT_NE(std::string(r.last_error).find("connect"), std::string::npos) << r.last_error;
}

// firmware-sim's --instrument-map: key=value pairs over the register map's keys, validated as a whole.
TEST(ModbusInstrument, RegisterMapListParsesValidatesAndDescribesItself) {
  namespace in = phalanx::linux_hal;
  in::InstrumentConfig c;
  c.scale = 1e-5;
  ASSERT_EQ(in::parseRegisterMap("table=holding,address=7,type=float32,word_order=little,scale=1,offset=-0.5,unit_id=3",
                                 "--map", c),
            "");
  EXPECT_EQ(c.table, "holding");
  EXPECT_EQ(c.address, 7u);
  EXPECT_EQ(c.type, "float32");
  EXPECT_EQ(c.word_order, "little");
  EXPECT_EQ(c.scale, 1.0);
  EXPECT_EQ(c.offset, -0.5);
  EXPECT_EQ(c.unit_id, 3u);
  EXPECT_EQ(in::describeRegisterMap(c), "unit 3 holding register 7 float32 word_order little scale 1 offset -0.5 N*m");
  const in::InstrumentConfig before = c;
  for (const auto& [list, problem] : std::vector<std::pair<std::string, std::string>>{
           {"type=int64", "--map.type: 'int64' is not"},
           {"scale=0", "--map.scale: must be finite and non-zero"},
           {"scale=1x", "--map.scale: expected a number, got '1x'"},
           {"address=65535", "--map.address: the value runs past register 65535"},
           {"address=-1", "--map.address: expected an integer in [0, 65535]"},
           {"unit_id=248", "--map.unit_id: must be in [0, 247]"},
           {"gain=2", "--map.gain: unknown key"},
           {"type=int16,", "--map: '' is not key=value"},
           {"=3", "--map: '=3' is not key=value"}}) {
    EXPECT_NE(in::parseRegisterMap(list, "--map", c).find(problem), std::string::npos) << list;
    EXPECT_EQ(c.type, before.type) << "a refused list changes nothing: " << list;
    EXPECT_EQ(c.address, before.address) << list;
  }
}

// Over RTU the server holds the pty's slave side open: with no client, the master must not read as hung up (the
// server thread spun on select() + EIO: 2.5 s of CPU in 3 s), and a second client after the first closed is served.
TEST(ModbusInstrument, RtuServerIdlesWithoutAClientAndServesTheNextOne) {
  const mb::InstrumentConfig map = loadCellMap();
  mb::SimInstrumentServer amp(map);
  std::string path;
  ASSERT_EQ(amp.startRtu(path), "");
  amp.set(0.125);
  auto cpuNs = [] {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return static_cast<uint64_t>(ts.tv_sec) * 1000000000ull + static_cast<uint64_t>(ts.tv_nsec);
  };
  const uint64_t cpu0 = cpuNs(), wall0 = monotonicNs();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const uint64_t cpu = cpuNs() - cpu0, wall = monotonicNs() - wall0;
  EXPECT_LT(static_cast<double>(cpu), 0.2 * static_cast<double>(wall)) << "CPU " << cpu / 1000 << " us in " << wall / 1000 << " us";
  for (int round = 0; round < 2; ++round) {
    mb::InstrumentConfig cfg = map;
    cfg.transport = "rtu";
    cfg.serial_device = path;
    mb::InstrumentClient client(cfg);
    ASSERT_EQ(client.start(), "");
    const auto r = waitFor(client, [](const mb::InstrumentReading& x) { return x.valid && !x.stale; });
    ASSERT_TRUE(r.valid) << "round " << round << ": " << r.last_error;
    EXPECT_NEAR(r.value, 0.125, 0.6e-5) << round;
    client.stop();
  }
}
