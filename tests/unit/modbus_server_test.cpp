// The Modbus server on its own (no daemon): raw frames over a loopback socket, so malformed input can be sent
// byte for byte. The register map with an independent client (mbpoll) is in tests/integration.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstring>
#include <thread>
#include <vector>

#include "phalanx/host/modbus/register_map.h"
#include "phalanx/host/modbus/server.h"
#include "phalanx/host/modbus/triple_buffer.h"

namespace mb = phalanx::host::modbus;

namespace {

class Client {
 public:
  explicit Client(unsigned port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  }
  ~Client() { ::close(fd_); }
  bool connected() const { return connected_; }
  void send(const std::vector<uint8_t>& bytes) { ASSERT_EQ(::write(fd_, bytes.data(), bytes.size()), static_cast<ssize_t>(bytes.size())); }
  /// Whole reply (waits up to timeout_ms for the first byte, then reads what follows); empty on timeout;
  /// {0xFF} when the server closed the connection.
  std::vector<uint8_t> receive(int timeout_ms = 1000) {
    std::vector<uint8_t> out;
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return out;
    uint8_t buf[300];
    const ssize_t n = ::read(fd_, buf, sizeof buf);
    if (n <= 0) return {0xFF};
    out.assign(buf, buf + n);
    return out;
  }

 private:
  int fd_ = -1;
  bool connected_ = false;
};

/// MBAP header + PDU.
std::vector<uint8_t> frame(uint16_t tid, std::vector<uint8_t> pdu, uint8_t unit = 1) {
  const auto len = static_cast<uint16_t>(pdu.size() + 1);
  const uint8_t head[7] = {static_cast<uint8_t>(tid >> 8), static_cast<uint8_t>(tid), 0, 0,
                           static_cast<uint8_t>(len >> 8), static_cast<uint8_t>(len), unit};
  std::vector<uint8_t> f(7 + pdu.size());
  std::memcpy(f.data(), head, 7);
  std::memcpy(f.data() + 7, pdu.data(), pdu.size());
  return f;
}

std::vector<uint8_t> readPdu(uint8_t fc, uint16_t addr, uint16_t count) {
  return {fc, static_cast<uint8_t>(addr >> 8), static_cast<uint8_t>(addr), static_cast<uint8_t>(count >> 8),
          static_cast<uint8_t>(count)};
}

std::vector<uint8_t> writeFloatPdu(uint16_t addr, float v) {
  uint32_t bits = 0;
  std::memcpy(&bits, &v, 4);
  return {0x10, static_cast<uint8_t>(addr >> 8), static_cast<uint8_t>(addr), 0, 2, 4,
          static_cast<uint8_t>(bits >> 24), static_cast<uint8_t>(bits >> 16), static_cast<uint8_t>(bits >> 8),
          static_cast<uint8_t>(bits)};
}

/// Exception code of a reply (0 if it is not an exception).
int exceptionOf(const std::vector<uint8_t>& r) {
  if (r.size() < 9 || (r[7] & 0x80) == 0) return 0;
  return r[8];
}

struct Fixture {
  explicit Fixture(bool writes) {
    mb::ServerOptions o;
    o.enabled = true;
    o.port = 0;
    o.writes_enabled = writes;
    o.byte_timeout_ms = 50;
    server = std::make_unique<mb::Server>(o, mb::WriteLimits{2, 0.3f});
    error = server->start();
  }
  std::unique_ptr<mb::Server> server;
  std::string error;
};

}  // namespace

TEST(ModbusTripleBuffer, ReaderSeesTheNewestValueAndWhetherItIsFresh) {
  mb::TripleBuffer<int> b;
  int v = 0;
  bool fresh = true;
  EXPECT_FALSE(b.read(v, &fresh));
  b.publish(1);
  b.publish(2);
  ASSERT_TRUE(b.read(v, &fresh));
  EXPECT_EQ(v, 2);
  EXPECT_TRUE(fresh);
  ASSERT_TRUE(b.read(v, &fresh));
  EXPECT_EQ(v, 2);
  EXPECT_FALSE(fresh);
  b.publish(3);
  ASSERT_TRUE(b.read(v, &fresh));
  EXPECT_EQ(v, 3);
}

TEST(ModbusTripleBuffer, ConcurrentReaderNeverSeesATornValue) {
  struct Pair {
    uint64_t a = 0, b = 0;
  };
  mb::TripleBuffer<Pair> buf;
  std::atomic<bool> done{false};
  std::thread producer([&] {
    for (uint64_t i = 1; i <= 200000; ++i) buf.publish(Pair{i, ~i});
    done = true;
  });
  uint64_t torn = 0, last = 0, backwards = 0;
  while (!done) {
    Pair p;
    if (buf.read(p)) {
      if (p.b != ~p.a) ++torn;
      if (p.a < last) ++backwards;
      last = p.a;
    }
  }
  producer.join();
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(backwards, 0u);
}

TEST(ModbusRegisterMap, AcceptsAWriteWithinTheLimitsAndRejectsBeyond) {
  uint16_t regs[mb::hold::kCount] = {};
  mb::RemoteCommand c;
  std::string why;
  const mb::WriteLimits lim{2, 0.3f};
  uint16_t f[2];
  mb::putF32(f, 0, 0.25f);
  EXPECT_EQ(mb::applyWrite(regs, mb::hold::kSetpoints, 2, f, lim, c, why), mb::WriteStatus::kOk) << why;
  EXPECT_FLOAT_EQ(c.setpoint[0], 0.25f);
  mb::putF32(f, 0, 0.31f);
  EXPECT_EQ(mb::applyWrite(regs, mb::hold::kSetpoints, 2, f, lim, c, why), mb::WriteStatus::kIllegalValue);
  EXPECT_NE(why.find("beyond the active limit"), std::string::npos) << why;
  EXPECT_FLOAT_EQ(mb::getF32(regs, mb::hold::kSetpoints), 0.25f) << "a rejected write changes nothing";
  mb::putF32(f, 0, std::nanf(""));
  EXPECT_EQ(mb::applyWrite(regs, mb::hold::kSetpoints + 2, 2, f, lim, c, why), mb::WriteStatus::kIllegalValue);
  mb::putF32(f, 0, 0.1f);
  EXPECT_EQ(mb::applyWrite(regs, mb::hold::kSetpoints + 4, 2, f, lim, c, why), mb::WriteStatus::kIllegalValue)
      << "channel 2 does not exist on a 2-channel device";
  EXPECT_EQ(mb::applyWrite(regs, mb::hold::kSetpoints + 1, 2, f, lim, c, why), mb::WriteStatus::kIllegalAddress)
      << "half a float";
  const uint16_t mode = 7;
  EXPECT_EQ(mb::applyWrite(regs, mb::hold::kMode, 1, &mode, lim, c, why), mb::WriteStatus::kIllegalValue);
  EXPECT_EQ(mb::applyWrite(regs, mb::hold::kCount, 1, &mode, lim, c, why), mb::WriteStatus::kIllegalAddress);
}

TEST(ModbusServer, ServesThePublishedSnapshotAsInputRegisters) {
  Fixture fx(false);
  ASSERT_EQ(fx.error, "");
  mb::LoopSnapshot s;
  s.device_type = 2;
  s.loop_state = mb::LoopState::kRunning;
  s.cycles = 123456;
  s.sample_count = 13;
  s.samples[7] = 0.125f;
  fx.server->publish(s);
  Client c(fx.server->port());
  ASSERT_TRUE(c.connected());
  c.send(frame(1, readPdu(0x04, 0, mb::in::kCount)));
  const auto r = c.receive();
  ASSERT_EQ(r.size(), 9u + 2u * mb::in::kCount);
  std::vector<uint16_t> regs(mb::in::kCount);
  for (size_t i = 0; i < regs.size(); ++i) regs[i] = static_cast<uint16_t>((r[9 + 2 * i] << 8) | r[10 + 2 * i]);
  EXPECT_EQ(regs[mb::in::kMapVersion], mb::kMapVersion);
  EXPECT_EQ(regs[mb::in::kDeviceType], 2);
  EXPECT_EQ(regs[mb::in::kLoopState], 1);
  EXPECT_EQ(mb::getU32(regs.data(), mb::in::kCycles), 123456u);
  EXPECT_FLOAT_EQ(mb::getF32(regs.data(), mb::in::kSamples + 14), 0.125f);
}

TEST(ModbusServer, ReadOnlyServerRejectsWritesWithIllegalFunction) {
  Fixture fx(false);
  ASSERT_EQ(fx.error, "");
  Client c(fx.server->port());
  c.send(frame(2, writeFloatPdu(mb::hold::kSetpoints, 0.1f)));
  EXPECT_EQ(exceptionOf(c.receive()), 1);
  mb::RemoteCommand rc;
  EXPECT_FALSE(fx.server->latestCommand(rc));
}

TEST(ModbusServer, WritesWithinLimitsReachTheLoopAndOthersGetExceptions) {
  Fixture fx(true);
  ASSERT_EQ(fx.error, "");
  Client c(fx.server->port());
  c.send(frame(3, writeFloatPdu(mb::hold::kSetpoints, 0.2f)));
  auto r = c.receive();
  ASSERT_GE(r.size(), 8u);
  EXPECT_EQ(r[7], 0x10);
  mb::RemoteCommand rc;
  ASSERT_TRUE(fx.server->latestCommand(rc));
  EXPECT_FLOAT_EQ(rc.setpoint[0], 0.2f);
  c.send(frame(4, writeFloatPdu(mb::hold::kSetpoints, 0.5f)));
  EXPECT_EQ(exceptionOf(c.receive()), 3) << "beyond the ±0.3 limit";
  c.send(frame(5, writeFloatPdu(mb::hold::kCount, 0.1f)));
  EXPECT_EQ(exceptionOf(c.receive()), 2) << "outside the holding map";
  c.send(frame(6, readPdu(0x04, mb::in::kCount - 1, 2)));
  EXPECT_EQ(exceptionOf(c.receive()), 2) << "read past the input map";
  c.send(frame(7, readPdu(0x03, 0, 0)));
  EXPECT_EQ(exceptionOf(c.receive()), 3) << "zero registers";
  c.send(frame(8, readPdu(0x03, 0, 126)));
  EXPECT_EQ(exceptionOf(c.receive()), 3) << "more than 125 registers";
  c.send(frame(9, {0x2B, 0x0E, 0x01, 0x00}));
  EXPECT_EQ(exceptionOf(c.receive()), 1) << "unsupported function";
  c.send(frame(10, {0x10, 0x00, 0x02, 0x00, 0x02, 0x03, 0, 0, 0}));
  EXPECT_EQ(exceptionOf(c.receive()), 3) << "byte count disagrees with the register count";
  ASSERT_TRUE(fx.server->latestCommand(rc));
  EXPECT_FLOAT_EQ(rc.setpoint[0], 0.2f) << "no rejected write reached the loop";
}

TEST(ModbusServer, IncompleteFrameDropsOnlyThatConnection) {
  Fixture fx(false);
  ASSERT_EQ(fx.error, "");
  Client bad(fx.server->port());
  Client good(fx.server->port());
  // A header announcing a read, then silence: the byte timeout (50 ms) ends that connection.
  bad.send({0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0x01, 0x04, 0x00});
  EXPECT_EQ(bad.receive(2000), std::vector<uint8_t>{0xFF});
  good.send(frame(11, readPdu(0x04, 0, 4)));
  EXPECT_EQ(good.receive().size(), 9u + 8u);
  // Garbage: a reply or a closed connection, never a hang or a crash; the server keeps serving.
  Client junk(fx.server->port());
  junk.send(std::vector<uint8_t>(40, 0xA5));
  junk.receive(2000);
  good.send(frame(12, readPdu(0x04, 0, 4)));
  EXPECT_EQ(good.receive().size(), 9u + 8u);
  EXPECT_GE(fx.server->stats().dropped.load(), 1u);
}

TEST(ModbusServer, ConnectionsBeyondTheLimitAreClosed) {
  mb::ServerOptions o;
  o.port = 0;
  o.max_clients = 2;
  mb::Server server(o, mb::WriteLimits{2, 0.3f});
  ASSERT_EQ(server.start(), "");
  Client a(server.port()), b(server.port()), c(server.port());
  a.send(frame(1, readPdu(0x04, 0, 1)));
  b.send(frame(1, readPdu(0x04, 0, 1)));
  EXPECT_EQ(a.receive().size(), 11u);
  EXPECT_EQ(b.receive().size(), 11u);
  EXPECT_EQ(c.receive(2000), std::vector<uint8_t>{0xFF});
  EXPECT_EQ(server.stats().refused_connections.load(), 1u);
}
