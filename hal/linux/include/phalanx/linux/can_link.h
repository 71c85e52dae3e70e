#pragma once
/// SocketCAN transport (classic CAN and CAN-FD) for both ends of a Phalanx link: the host daemon and the
/// simulated firmware. Maps whole protocol messages to frames (phalanx/protocol/can.h), filters by node id in the
/// kernel, follows the controller state from error frames (error-warning/passive, bus-off, restarted), never
/// blocks: frames the kernel cannot take now (EAGAIN/ENOBUFS, link down) wait in a bounded user-space queue,
/// where a newer Command or Telemetry replaces an older one that has not started to go out.
#include <cstddef>
#include <cstdint>
#include <string>

#include "phalanx/hal/hal.h"
#include "phalanx/protocol/can.h"

namespace phalanx::linux_hal {

enum class CanBusState : uint8_t { kActive = 0, kWarning = 1, kPassive = 2, kBusOff = 3, kDown = 4 };
const char* canBusStateName(CanBusState s);

struct CanLinkStats {
  uint64_t tx_frames = 0;            ///< frames the kernel accepted
  uint64_t tx_messages = 0;          ///< messages queued whole
  uint64_t tx_dropped_full = 0;      ///< messages refused: user-space queue full
  uint64_t tx_dropped_bus_off = 0;   ///< messages refused while bus-off or down
  uint64_t tx_not_representable = 0; ///< messages this flavour cannot carry (compact limits)
  uint64_t tx_superseded = 0;        ///< queued messages replaced by a newer one of the same kind before going out
  uint64_t tx_would_block = 0;       ///< writes the kernel deferred (EAGAIN / ENOBUFS: TX queue full)
  uint64_t tx_link_down = 0;         ///< writes refused with ENETDOWN
  uint64_t rx_frames = 0;            ///< data frames read
  uint64_t rx_kernel_dropped = 0;    ///< frames the kernel dropped because our socket queue was full (SO_RXQ_OVFL)
  uint64_t error_frames = 0;
  uint64_t bus_off_events = 0;
  uint64_t restarts = 0;             ///< CAN_ERR_RESTARTED seen (controller back from bus-off)
  uint64_t no_ack = 0;               ///< CAN_ERR_ACK: nobody acknowledged (no other node on the bus)
  uint64_t protocol_errors = 0;      ///< CAN_ERR_PROT (stuff, form, bit errors)
  uint64_t controller_overflow = 0;  ///< CAN_ERR_CRTL RX/TX overflow
  uint64_t last_rx_kernel_ns = 0;    ///< kernel receive timestamp of the last frame (CLOCK_REALTIME)
};

class CanLink : public hal::PacketLink {
 public:
  struct Options {
    std::string ifname;
    uint8_t node = 1;
    protocol::can::Flavor flavor = protocol::can::Flavor::kFd;
    protocol::can::Role role = protocol::can::Role::kHost;
    bool bit_rate_switch = true;  ///< CAN-FD: data phase at the data bit rate
  };

  CanLink() = default;
  CanLink(const CanLink&) = delete;
  CanLink& operator=(const CanLink&) = delete;
  ~CanLink() override;

  /// Open a raw CAN socket on opt.ifname. Returns an empty string or what went wrong.
  std::string open(const Options& opt);
  /// Use an already open datagram/seqpacket descriptor carrying struct can(fd)_frame (tests, benchmarks).
  void adopt(int fd, const Options& opt);
  void close();

  bool send(uint8_t msg_id, const uint8_t* payload, size_t len) override;
  bool receive(uint8_t& msg_id, uint8_t* payload, size_t& len) override;
  hal::PacketRxStats rxStats() const override;

  /// Write queued frames until the kernel defers; never blocks. False only on an unexpected hard error.
  bool flush();
  /// The device this link carries (device side: at start; the host learns it from the HelloAck).
  void setDevice(protocol::DeviceType type, uint16_t tick_rate_hz) { mapper_.setDevice(type, tick_rate_hz); }

  CanBusState state() const { return state_; }
  const CanLinkStats& stats() const { return stats_; }
  const protocol::can::RxStats& mapperStats() const { return mapper_.stats(); }
  /// Why the last message counted in tx_not_representable was refused (nullptr if none was).
  const char* lastRefusal() const { return last_refusal_; }
  size_t queued() const { return q_len_; }
  const std::string& error() const { return error_; }
  int fd() const { return fd_; }

  /// Frames of the user-space TX queue: a full classic tick of the largest device, four times over.
  static constexpr size_t kTxQueueFrames = 16;

 private:
  struct Entry {
    protocol::can::CanFrame frame;
    uint8_t msg_id;
    uint32_t serial;
  };
  bool readFrame(protocol::can::CanFrame& out);
  void handleErrorFrame(uint32_t can_id, const uint8_t* data);
  void dropQueued(uint8_t msg_id);

  int fd_ = -1;
  Options opt_;
  protocol::can::Mapper mapper_{protocol::can::Flavor::kFd, protocol::can::Role::kHost, 1};
  CanBusState state_ = CanBusState::kActive;
  CanLinkStats stats_;
  std::string error_;
  Entry q_[kTxQueueFrames] = {};
  size_t q_len_ = 0;
  uint32_t next_serial_ = 1;
  uint32_t started_serial_ = 0;
  const char* last_refusal_ = nullptr;  ///< serial of the message whose first frame went out last
};

}  // namespace phalanx::linux_hal
