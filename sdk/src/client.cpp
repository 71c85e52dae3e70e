// libphalanx: the client side of phalanxd's client channel (host/include/phalanx/host/client/wire.h).
#include "phalanx/client.hpp"

#include <linux/futex.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>

#include "phalanx/glove/kinematics.h"
#include "phalanx/host/client/wire.h"

namespace phalanx {
namespace wire = client_wire;

static_assert(PHALANX_MAX_SAMPLES == wire::kMaxSamples && PHALANX_MAX_SETPOINTS == wire::kMaxSetpoints &&
                  PHALANX_MAX_MODEL_VALUES == wire::kMaxModelValues,
              "C ABI and wire sizes");
static_assert(sizeof(phalanx_spring) == sizeof(wire::SpringElement), "spring layout");

namespace {

int connectSocket(const std::string& path) {
  if (path.empty() || path.size() >= sizeof(sockaddr_un{}.sun_path)) {
    throw Error(PHALANX_EARG, "socket path '" + path + "' is empty or too long");
  }
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw Error(PHALANX_ECONNECT, std::string("socket: ") + std::strerror(errno));
  sockaddr_un sa{};
  sa.sun_family = AF_UNIX;
  std::memcpy(sa.sun_path, path.c_str(), path.size());
  if (::connect(fd, reinterpret_cast<sockaddr*>(&sa), sizeof sa) != 0) {
    const int e = errno;
    ::close(fd);
    throw Error(PHALANX_ECONNECT, "cannot connect to phalanxd at " + path + ": " + std::strerror(e));
  }
  timeval tv{2, 0};  // the daemon answers from its socket thread at once; 2 s bounds a wedged one
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  return fd;
}

/// The reply and the shared-memory descriptor attached to it (-1 if none).
int receiveReply(int fd, wire::ConnectReply& reply) {
  iovec iov{&reply, sizeof reply};
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(int))] = {};
  msg.msg_control = control;
  msg.msg_controllen = sizeof control;
  const ssize_t n = ::recvmsg(fd, &msg, MSG_WAITALL | MSG_CMSG_CLOEXEC);
  if (n != static_cast<ssize_t>(sizeof reply)) {
    throw Error(PHALANX_ECONNECT, n == 0 ? "phalanxd closed the connection (peer credentials refused?)"
                                         : "no valid answer from phalanxd");
  }
  int memfd = -1;
  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
    if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_RIGHTS) std::memcpy(&memfd, CMSG_DATA(c), sizeof(int));
  }
  return memfd;
}

}  // namespace

struct Client::Impl {
  int fd = -1;
  wire::SharedChannel* channel = nullptr;
  uint32_t generation = 0;
  uint32_t command_seq = 0;
  uint32_t last_state_seq = 0;
  uint16_t last_telemetry_seq = 0;
  bool released = false;
  DeviceInfo info{};

  bool readState(State& out) {
    wire::StatePayload p;
    for (int attempt = 0; attempt < 64; ++attempt) {  // the daemon's write is a few hundred ns
      if (wire::seqlockTryRead(channel->state.seq, channel->state.payload, p)) {
        if (p.generation != generation) return false;
        convert(p, out);
        last_telemetry_seq = p.telemetry_seq;
        return true;
      }
    }
    return false;
  }

  static void convert(const wire::StatePayload& p, State& s) {
    s.cycle = p.cycle;
    s.daemon_time_ns = p.daemon_time_ns;
    s.telemetry_rx_ns = p.telemetry_rx_ns;
    s.device_time_us = p.device_time_us;
    s.telemetry_seq = p.telemetry_seq;
    s.device_mode = p.device_mode;
    s.fault_bits = p.fault_bits;
    s.control = static_cast<int>(p.control);
    s.force_off_cause = static_cast<int>(p.force_off_cause);
    s.commands_used = p.commands_used;
    s.refused_invalid = p.refused_invalid;
    s.refused_other_source = p.refused_other_source;
    s.limited = p.limited;
    s.force_offs = p.force_offs;
    s.achieved_rate_hz = p.achieved_rate_hz;
    std::memcpy(s.sample, p.sample, sizeof s.sample);
    std::memcpy(s.setpoint_sent, p.setpoint_sent, sizeof s.setpoint_sent);
    s.model_saturated = p.model_saturated;
    s.fallback_cycles = p.fallback_cycles;
    s.rendered = p.rendered;
    s.model_scale = p.model_scale;
    std::memcpy(s.glove.joint_rad, p.glove.joint_rad, sizeof s.glove.joint_rad);
    std::memcpy(s.glove.fingertip, p.glove.fingertip, sizeof s.glove.fingertip);
    std::memcpy(s.glove.fingertip_velocity, p.glove.fingertip_velocity, sizeof s.glove.fingertip_velocity);
    std::memcpy(s.glove.pad_force_N, p.glove.pad_force_N, sizeof s.glove.pad_force_N);
    std::memcpy(s.glove.valid, p.glove.valid, sizeof s.glove.valid);
    std::memcpy(s.sea.flexion_rad, p.sea.flexion_rad, sizeof s.sea.flexion_rad);
    std::memcpy(s.sea.flexion_rate_rad_s, p.sea.flexion_rate_rad_s, sizeof s.sea.flexion_rate_rad_s);
    std::memcpy(s.sea.finger_torque_Nm, p.sea.finger_torque_Nm, sizeof s.sea.finger_torque_Nm);
    std::memcpy(s.sea.exo_torque_Nm, p.sea.exo_torque_Nm, sizeof s.sea.exo_torque_Nm);
    s.sea.valid = p.sea.valid;
    std::memcpy(s.pen.centre_m, p.pen.centre_m, sizeof s.pen.centre_m);
    std::memcpy(s.pen.axis, p.pen.axis, sizeof s.pen.axis);
    std::memcpy(s.pen.tip_m, p.pen.tip_m, sizeof s.pen.tip_m);
    s.pen.theta_x_rad = p.pen.theta_x_rad;
    s.pen.theta_z_rad = p.pen.theta_z_rad;
    std::memcpy(s.pen.velocity_m_s, p.pen.velocity_m_s, sizeof s.pen.velocity_m_s);
    std::memcpy(s.pen.force_N, p.pen.force_N, sizeof s.pen.force_N);
    std::memcpy(s.pen.torque_Nm, p.pen.torque_Nm, sizeof s.pen.torque_Nm);
    s.pen.valid = p.pen.valid;
    s.command_seq_used = p.command_seq_used;
  }

  void write(const Command& cmd) {
    wire::CommandPayload p;
    p.generation = generation;
    p.command_seq = ++command_seq;
    p.for_telemetry_seq = last_telemetry_seq;
    p.mode = static_cast<uint8_t>(cmd.mode);
    for (size_t i = 0; i < wire::kMaxSetpoints; ++i) p.setpoint[i] = cmd.setpoint[i];
    p.kind = static_cast<wire::CommandKind>(cmd.kind);
    for (size_t i = 0; i < wire::kMaxModelValues; ++i) p.model[i] = cmd.model[i];
    p.fallback.kind = cmd.fallback.enabled != 0 ? wire::FallbackKind::kSpring : wire::FallbackKind::kNone;
    std::memcpy(p.fallback.element, cmd.fallback.element, sizeof p.fallback.element);
    wire::seqlockWrite(channel->command.seq, channel->command.payload, p);
  }
};

Client::Client(const ConnectOptions& options) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.fd = connectSocket(options.socket_path);
  wire::ConnectRequest req;
  req.deadline_ms = static_cast<uint16_t>(options.deadline_ms > 65535 ? 65535 : options.deadline_ms);
  req.fallback = static_cast<wire::Fallback>(options.fallback);
  wire::ConnectReply reply;
  int memfd = -1;
  try {
    if (::send(m.fd, &req, sizeof req, MSG_NOSIGNAL) != static_cast<ssize_t>(sizeof req)) {
      throw Error(PHALANX_ECONNECT, std::string("send: ") + std::strerror(errno));
    }
    memfd = receiveReply(m.fd, reply);
    if (reply.magic != wire::kMagic) throw Error(PHALANX_ECONNECT, "not a phalanxd client socket");
    if (reply.status != wire::ConnectStatus::kOk) {
      reply.message[sizeof reply.message - 1] = 0;
      throw Error(PHALANX_EREFUSED, std::string("phalanxd refused the connection: ") + reply.message);
    }
    if (memfd < 0) throw Error(PHALANX_ECONNECT, "phalanxd sent no shared memory");
    void* p = ::mmap(nullptr, sizeof(wire::SharedChannel), PROT_READ | PROT_WRITE, MAP_SHARED, memfd, 0);
    ::close(memfd);
    if (p == MAP_FAILED) throw Error(PHALANX_ECONNECT, std::string("mmap: ") + std::strerror(errno));
    m.channel = static_cast<wire::SharedChannel*>(p);
  } catch (...) {
    ::close(m.fd);
    throw;
  }
  m.generation = reply.generation;
  std::memcpy(m.info.device_name, reply.device_name, sizeof m.info.device_name);
  m.info.device_name[sizeof m.info.device_name - 1] = 0;
  m.info.device_type = reply.device_type;
  m.info.setpoint_count = reply.setpoint_count;
  m.info.sample_count = reply.sample_count;
  m.info.setpoint_limit = reply.setpoint_limit;
  m.info.rate_hz = reply.rate_hz;
  m.info.deadline_ms = reply.deadline_ms;
  m.info.firmware_build_id = reply.firmware_build_id;
}

Client::~Client() {
  release();
  if (impl_->channel != nullptr) ::munmap(impl_->channel, sizeof(wire::SharedChannel));
  if (impl_->fd >= 0) ::close(impl_->fd);
}

void Client::release() {
  Impl& m = *impl_;
  if (m.released || m.fd < 0) return;
  wire::Release rel;
  rel.generation = m.generation;
  ::send(m.fd, &rel, sizeof rel, MSG_NOSIGNAL);
  m.released = true;
}

const DeviceInfo& Client::device() const { return impl_->info; }

bool Client::getState(State& out) {
  if (!impl_->readState(out)) return false;
  impl_->last_state_seq = impl_->channel->state.seq.load(std::memory_order_acquire);
  return true;
}

bool Client::waitState(State& out, int timeout_ms) {
  Impl& m = *impl_;
  timespec end{};
  clock_gettime(CLOCK_MONOTONIC, &end);
  const int64_t end_ns = static_cast<int64_t>(end.tv_sec) * 1000000000 + end.tv_nsec + int64_t{timeout_ms} * 1000000;
  for (;;) {
    const uint32_t seq = m.channel->state.seq.load(std::memory_order_acquire);
    if ((seq & 1u) == 0 && seq != m.last_state_seq && m.readState(out)) {
      m.last_state_seq = seq;
      return true;
    }
    timespec now{};
    clock_gettime(CLOCK_MONOTONIC, &now);
    const int64_t left_ns = end_ns - (static_cast<int64_t>(now.tv_sec) * 1000000000 + now.tv_nsec);
    if (left_ns <= 0) return false;
    timespec rel{static_cast<time_t>(left_ns / 1000000000), static_cast<long>(left_ns % 1000000000)};
    // Sleeps until the daemon's futex wake after its next state write (or the timeout).
    syscall(SYS_futex, reinterpret_cast<uint32_t*>(&m.channel->state.seq), FUTEX_WAIT, seq, &rel, nullptr, 0);
  }
}

bool Client::setCommand(const Command& cmd) {
  impl_->write(cmd);
  return true;
}

bool Client::setFingertipForces(const std::array<double, PHALANX_GLOVE_FINGERS>& force_N) {
  if (impl_->info.device_type != 1) return false;  // glove5 only
  Command cmd;
  for (size_t i = 0; i < force_N.size(); ++i) cmd.setpoint[i] = static_cast<float>(force_N[i]);
  impl_->write(cmd);
  return true;
}

void Command::fingerTorques(double mcp_Nm, double pip_Nm) {
  kind = CommandKind::kSeaFingerTorque;
  model = {};
  model[0] = static_cast<float>(mcp_Nm);
  model[1] = static_cast<float>(pip_Nm);
}

void Command::penWrench(const std::array<double, 3>& force_N, const std::array<double, 3>& torque_Nm) {
  kind = CommandKind::kPenWrench;
  model = {};
  for (size_t i = 0; i < 3; ++i) {
    model[i] = static_cast<float>(force_N[i]);
    model[3 + i] = static_cast<float>(torque_Nm[i]);
  }
}

void Command::fingertipForces(const std::array<std::array<double, 2>, PHALANX_GLOVE_FINGERS>& force_N) {
  kind = CommandKind::kGloveFingertipForce;
  model = {};
  for (size_t f = 0; f < force_N.size(); ++f) {
    model[2 * f] = static_cast<float>(force_N[f][0]);
    model[2 * f + 1] = static_cast<float>(force_N[f][1]);
  }
}

bool Client::set(const Command& cmd) {
  impl_->write(cmd);
  return true;
}

bool Client::setFingerTorques(double mcp_Nm, double pip_Nm, const FallbackSpring* fallback) {
  if (impl_->info.device_type != 2) return false;  // sea_finger only
  Command cmd;
  cmd.fingerTorques(mcp_Nm, pip_Nm);
  if (fallback != nullptr) cmd.fallback = *fallback;
  impl_->write(cmd);
  return true;
}

bool Client::setPenWrench(const std::array<double, 3>& force_N, const std::array<double, 3>& torque_Nm,
                          const FallbackSpring* fallback) {
  if (impl_->info.device_type != 3) return false;  // pantograph only
  Command cmd;
  cmd.penWrench(force_N, torque_Nm);
  if (fallback != nullptr) cmd.fallback = *fallback;
  impl_->write(cmd);
  return true;
}

double Client::achievedRateHz() {
  State s{};
  return getState(s) ? static_cast<double>(s.achieved_rate_hz) : 0.0;
}

int Client::runServo(const std::function<bool(const State&, Command&)>& cb, State* last) {
  State s{};
  Command cmd;
  for (;;) {
    if (!waitState(s, 1000)) continue;  // a paused daemon: keep waiting (the daemon owns the timeouts)
    if (last != nullptr) *last = s;
    if (s.control == PHALANX_CONTROL_FORCED_OFF) return PHALANX_EFORCED_OFF;
    if (!cb(s, cmd)) return PHALANX_OK;
    impl_->write(cmd);
  }
}

std::array<double, 3> gloveFingertip(const State& s, int finger) {
  const auto id = static_cast<glove::FingerId>(finger);
  const glove::Model<double> model = glove::defaultModel<double>(id);
  const glove::Vec3<double> alpha{s.sample[3 * finger], s.sample[3 * finger + 1], s.sample[3 * finger + 2]};
  return glove::tipPoseFromAlpha(model.mech, alpha);
}

}  // namespace phalanx
