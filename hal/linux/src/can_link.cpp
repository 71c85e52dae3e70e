#include "phalanx/linux/can_link.h"

#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>

namespace phalanx::linux_hal {

using protocol::can::CanFrame;
using protocol::can::Flavor;

const char* canBusStateName(CanBusState s) {
  switch (s) {
    case CanBusState::kActive: return "error-active";
    case CanBusState::kWarning: return "error-warning";
    case CanBusState::kPassive: return "error-passive";
    case CanBusState::kBusOff: return "bus-off";
    case CanBusState::kDown: return "down";
  }
  return "unknown";
}

CanLink::~CanLink() { close(); }

void CanLink::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void CanLink::adopt(int fd, const Options& opt) {
  close();
  fd_ = fd;
  opt_ = opt;
  mapper_ = protocol::can::Mapper(opt.flavor, opt.role, opt.node);
  state_ = CanBusState::kActive;
  stats_ = {};
  q_len_ = 0;
  error_.clear();
}

std::string CanLink::open(const Options& opt) {
  auto fail = [&](const std::string& what, int fd) {
    const std::string e = what + ": " + std::strerror(errno);
    if (fd >= 0) ::close(fd);
    return e;
  };
  if (opt.node < protocol::can::kMinNode || opt.node > protocol::can::kMaxNode) {
    return "CAN node id " + std::to_string(opt.node) + " is outside 1..63";
  }
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) return fail("cannot open a CAN socket (is the kernel built with CAN_RAW?)", -1);
  ifreq ifr{};
  if (opt.ifname.empty() || opt.ifname.size() >= sizeof ifr.ifr_name) {
    ::close(fd);
    return "bad CAN interface name '" + opt.ifname + "'";
  }
  std::strncpy(ifr.ifr_name, opt.ifname.c_str(), sizeof ifr.ifr_name - 1);
  if (ioctl(fd, SIOCGIFINDEX, &ifr) != 0) return fail("no CAN interface '" + opt.ifname + "'", fd);
  const int ifindex = ifr.ifr_ifindex;
  if (protocol::can::isFd(opt.flavor)) {
    if (ioctl(fd, SIOCGIFMTU, &ifr) != 0) return fail("SIOCGIFMTU " + opt.ifname, fd);
    if (ifr.ifr_mtu != CANFD_MTU) {
      ::close(fd);
      return opt.ifname + " is not CAN-FD capable (mtu " + std::to_string(ifr.ifr_mtu) +
             "); use @classic or configure it for CAN-FD (vcan: ip link set " + opt.ifname + " mtu 72)";
    }
    const int on = 1;
    if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) != 0) return fail("CAN_RAW_FD_FRAMES", fd);
  }
  // Kernel filter: only frames addressed to our node id (low 6 bits). Foreign functions, wrong directions and
  // extended/remote frames that carry our node id still reach us so that they are rejected and counted.
  can_filter filter{};
  filter.can_id = opt.node;
  filter.can_mask = 0x3Fu;
  if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, &filter, sizeof filter) != 0) return fail("CAN_RAW_FILTER", fd);
  const can_err_mask_t err_mask = CAN_ERR_MASK;
  if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) != 0) {
    return fail("CAN_RAW_ERR_FILTER", fd);
  }
  const int on = 1;
  if (setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) != 0) return fail("SO_TIMESTAMPNS", fd);
  if (setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) != 0) return fail("SO_RXQ_OVFL", fd);
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifindex;
  if (bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) return fail("bind " + opt.ifname, fd);
  adopt(fd, opt);
  return {};
}

void CanLink::dropQueued(uint8_t msg_id) {
  // Remove queued frames of older messages of this kind that have not started to go out: the new one carries
  // the full state again, and a stale command or telemetry frame is worse than none.
  size_t w = 0;
  uint32_t last_serial = 0;
  for (size_t r = 0; r < q_len_; ++r) {
    const Entry& e = q_[r];
    if (e.msg_id == msg_id && e.serial != started_serial_) {
      if (e.serial != last_serial) ++stats_.tx_superseded;
      last_serial = e.serial;
      continue;
    }
    q_[w++] = e;
  }
  q_len_ = w;
}

bool CanLink::send(uint8_t msg_id, const uint8_t* payload, size_t len) {
  if (fd_ < 0) return false;
  if (state_ == CanBusState::kBusOff) {
    ++stats_.tx_dropped_bus_off;
    return false;
  }
  CanFrame frames[protocol::can::kMaxFramesPerMessage];
  protocol::can::EncodeStatus status;
  const size_t n = mapper_.encode(msg_id, payload, len, frames, status);
  if (n == 0) {
    if (status == protocol::can::EncodeStatus::kNotRepresentable) last_refusal_ = mapper_.refusal();
    ++stats_.tx_not_representable;
    return false;
  }
  if (msg_id == static_cast<uint8_t>(protocol::MsgId::kCommand) ||
      msg_id == static_cast<uint8_t>(protocol::MsgId::kTelemetry)) {
    dropQueued(msg_id);
  }
  if (kTxQueueFrames - q_len_ < n) {
    ++stats_.tx_dropped_full;
    return false;
  }
  const uint32_t serial = next_serial_++;
  for (size_t i = 0; i < n; ++i) q_[q_len_++] = Entry{frames[i], msg_id, serial};
  ++stats_.tx_messages;
  flush();
  return true;
}

bool CanLink::flush() {
  size_t sent = 0;
  bool ok = true;
  while (fd_ >= 0 && sent < q_len_) {
    const CanFrame& f = q_[sent].frame;
    ssize_t want;
    ssize_t n;
    if (f.fd) {
      canfd_frame cf{};
      cf.can_id = f.id;
      cf.len = f.len;
      cf.flags = opt_.bit_rate_switch ? CANFD_BRS : 0;
      std::memcpy(cf.data, f.data, f.len);
      want = CANFD_MTU;
      n = ::write(fd_, &cf, CANFD_MTU);
    } else {
      can_frame cf{};
      cf.can_id = f.id;
      cf.len = f.len;
      std::memcpy(cf.data, f.data, f.len);
      want = CAN_MTU;
      n = ::write(fd_, &cf, CAN_MTU);
    }
    if (n == want) {
      started_serial_ = q_[sent].serial;
      ++stats_.tx_frames;
      ++sent;
      if (state_ == CanBusState::kDown) state_ = CanBusState::kActive;
      continue;
    }
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS || errno == EINTR)) {
      ++stats_.tx_would_block;  // the kernel's TX queue is full: keep the frame, try again next cycle
      break;
    }
    if (n < 0 && errno == ENETDOWN) {
      ++stats_.tx_link_down;
      state_ = CanBusState::kDown;
      break;
    }
    error_ = std::string("CAN write: ") + (n < 0 ? std::strerror(errno) : "short write");
    ok = false;
    break;
  }
  if (sent > 0) {
    std::memmove(q_, q_ + sent, (q_len_ - sent) * sizeof(Entry));
    q_len_ -= sent;
  }
  return ok;
}

void CanLink::handleErrorFrame(uint32_t can_id, const uint8_t* data) {
  ++stats_.error_frames;
  if (can_id & CAN_ERR_BUSOFF) {
    if (state_ != CanBusState::kBusOff) ++stats_.bus_off_events;
    state_ = CanBusState::kBusOff;
    q_len_ = 0;  // what was queued is stale by the time the controller is back
  }
  if (can_id & CAN_ERR_RESTARTED) {
    ++stats_.restarts;
    state_ = CanBusState::kActive;
  }
  if (can_id & CAN_ERR_ACK) ++stats_.no_ack;
  if (can_id & CAN_ERR_PROT) ++stats_.protocol_errors;
  if ((can_id & CAN_ERR_CRTL) && state_ != CanBusState::kBusOff) {
    const uint8_t c = data[1];
    if (c & (CAN_ERR_CRTL_RX_OVERFLOW | CAN_ERR_CRTL_TX_OVERFLOW)) ++stats_.controller_overflow;
    if (c & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) {
      state_ = CanBusState::kPassive;
    } else if (c & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) {
      state_ = CanBusState::kWarning;
    } else if (c & CAN_ERR_CRTL_ACTIVE) {
      state_ = CanBusState::kActive;
    }
  }
}

bool CanLink::readFrame(CanFrame& out) {
  for (;;) {
    canfd_frame cf{};
    iovec iov{&cf, sizeof cf};
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timespec)) + CMSG_SPACE(sizeof(uint32_t))];
    msghdr msg{};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
    const ssize_t n = ::recvmsg(fd_, &msg, MSG_DONTWAIT);
    if (n < 0) return false;  // EAGAIN: nothing pending (other errors show up on write)
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
      if (c->cmsg_level != SOL_SOCKET) continue;
      if (c->cmsg_type == SCM_TIMESTAMPNS) {
        timespec ts;
        std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
        stats_.last_rx_kernel_ns = static_cast<uint64_t>(ts.tv_sec) * 1000000000ull + static_cast<uint64_t>(ts.tv_nsec);
      } else if (c->cmsg_type == SO_RXQ_OVFL) {
        uint32_t dropped;
        std::memcpy(&dropped, CMSG_DATA(c), sizeof dropped);
        stats_.rx_kernel_dropped = dropped;  // cumulative count kept by the kernel
      }
    }
    if (n != CAN_MTU && n != CANFD_MTU) continue;  // not a CAN frame: ignore
    if (cf.can_id & CAN_ERR_FLAG) {
      handleErrorFrame(cf.can_id, cf.data);
      continue;
    }
    ++stats_.rx_frames;
    // Frames arriving means the interface is up again. Bus-off ends only with CAN_ERR_RESTARTED, which the
    // kernel sends on every restart (manual or restart-ms): a frame still queued from before proves nothing.
    if (state_ == CanBusState::kDown) state_ = CanBusState::kActive;
    out.fd = n == CANFD_MTU;
    out.extended = (cf.can_id & CAN_EFF_FLAG) != 0;
    out.remote = (cf.can_id & CAN_RTR_FLAG) != 0;
    out.id = cf.can_id & (out.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
    out.len = cf.len > 64 ? 64 : cf.len;
    std::memcpy(out.data, cf.data, out.len);
    return true;
  }
}

bool CanLink::receive(uint8_t& msg_id, uint8_t* payload, size_t& len) {
  if (fd_ < 0) return false;
  // Bounded: a flood of frames that never complete a message cannot hold the caller.
  for (int i = 0; i < 64; ++i) {
    CanFrame f;
    if (!readFrame(f)) return false;
    if (mapper_.decode(f, msg_id, payload, len)) return true;
  }
  return false;
}

hal::PacketRxStats CanLink::rxStats() const {
  const protocol::can::RxStats& m = mapper_.stats();
  hal::PacketRxStats r;
  r.bad_id = m.bad_id;
  r.bad_length = m.bad_length;
  r.crc = m.crc;
  r.sequence = m.sequence;
  return r;
}

}  // namespace phalanx::linux_hal
