#pragma once
/// USB transport of the host daemon through libusb: a vendor-specific interface (class 0xFF) with one bulk OUT
/// and one bulk IN endpoint, one protocol message body per bulk transfer (docs/protocol.md: `id | payload |
/// crc16`, no COBS). Asynchronous: IN transfers stay submitted all the time, OUT transfers come from a fixed pool,
/// and libusb's events are handled with a zero timeout, so no call ever blocks the control loop.
/// Hot-unplug: a transfer that ends with LIBUSB_TRANSFER_NO_DEVICE (or a submit that fails with
/// LIBUSB_ERROR_NO_DEVICE) takes the link down; every transfer is cancelled and reaped without blocking, nothing
/// queued before the unplug is ever sent afterwards, and reconnect() finds the device again in sysfs (not through
/// libusb's udev-backed device list, which needs a running udevd to learn of a re-plug) and opens its
/// /dev/bus/usb node with libusb_wrap_sys_device.
#include <cstddef>
#include <cstdint>
#include <string>

#include "phalanx/hal/hal.h"
#include "phalanx/linux/usb_out_queue.h"

struct libusb_context;
struct pollfd;
struct libusb_device_handle;
struct libusb_transfer;

namespace phalanx::linux_hal {

struct UsbLinkStats {
  uint64_t tx_messages = 0;          ///< OUT transfers submitted
  uint64_t tx_completed = 0;         ///< OUT transfers the device took whole
  uint64_t tx_queued = 0;            ///< messages held back because every OUT transfer was in flight
  uint64_t tx_superseded = 0;        ///< held-back commands replaced by a newer one before they could go out
  uint64_t tx_dropped_busy = 0;      ///< messages refused: every OUT transfer in flight and the queue full
  uint64_t tx_discarded_unplug = 0;  ///< held-back messages discarded because the device went away
  uint64_t tx_dropped_offline = 0;   ///< messages refused: no device
  uint64_t tx_failed = 0;            ///< OUT transfers that ended in an error other than unplug
  uint64_t rx_transfers = 0;         ///< IN transfers completed with data
  uint64_t rx_overflow = 0;          ///< received bodies dropped because the receive ring was full
  uint64_t rx_failed = 0;            ///< IN transfers that ended in an error other than unplug
  uint64_t disconnects = 0;          ///< hot-unplugs seen
  uint64_t connects = 0;             ///< successful opens (the first one included)
  uint64_t reconnect_attempts = 0;   ///< reconnect() calls that scanned for the device
};

class UsbLink : public hal::PacketLink {
 public:
  struct Options {
    uint16_t vid = 0;
    uint16_t pid = 0;
    std::string serial;  ///< empty: the first device with vid:pid
  };
  enum class State : uint8_t { kClosed = 0, kConnected = 1, kDraining = 2 };

  UsbLink() = default;
  UsbLink(const UsbLink&) = delete;
  UsbLink& operator=(const UsbLink&) = delete;
  ~UsbLink() override;

  /// Find the device, claim its vendor interface and start receiving. Returns an empty string or what is wrong.
  std::string open(const Options& opt);
  /// Try to open the device again after an unplug (no-op while connected or still draining). Empty on success.
  std::string reconnect();
  /// Cancel everything and close (blocks until libusb has returned every transfer: not for the control loop).
  void close();

  bool send(uint8_t msg_id, const uint8_t* payload, size_t len) override;
  bool receive(uint8_t& msg_id, uint8_t* payload, size_t& len) override;
  hal::PacketRxStats rxStats() const override { return rx_stats_; }
  /// Handle pending libusb events without waiting; false once the device is gone (connected() then false).
  bool service();
  /// libusb's descriptors to wait on for completions (at most `max`, with their events), for a caller that
  /// sleeps in poll()/ppoll() and then calls service() (or receive()). Re-read from libusb only when libusb
  /// reported a change (device opened or closed): no allocation per call. 0 before open().
  size_t pollFds(pollfd* fds, size_t max);

  bool connected() const { return state_ == State::kConnected; }
  State state() const { return state_; }
  /// Incremented by every successful (re)connect: a new value means a new device session (re-handshake).
  uint32_t generation() const { return generation_; }
  const UsbLinkStats& stats() const { return stats_; }
  const std::string& error() const { return error_; }
  /// "bus-port.path" of the open device in sysfs, and its bus/address (for reports).
  const std::string& where() const { return where_; }

  static constexpr size_t kInTransfers = 64;   ///< IN transfers kept submitted (see docs/usb.md)
  static constexpr size_t kOutTransfers = 8;   ///< OUT transfers in flight at most (see docs/usb.md)
  static constexpr size_t kRxRing = 128;       ///< received bodies waiting for receive()
  static constexpr size_t kInBufferBytes = 512;  ///< one high-speed max packet; every body is shorter

 private:
  struct Xfer {
    libusb_transfer* t = nullptr;
    UsbLink* link = nullptr;
    bool in_flight = false;
    bool is_in = false;
    uint8_t buf[kInBufferBytes] = {};
  };
  static void onTransfer(libusb_transfer* t);
  void complete(Xfer& x);
  void lost(const char* why);
  bool submitIn(Xfer& x);
  /// Submit held-back messages while OUT transfers are free. False if the device went away meanwhile.
  bool pumpOut();
  /// Submit one body on a free OUT transfer: 1 submitted, 0 no free transfer, -1 failed (counted).
  int submitOut(const uint8_t* body, size_t len);
  std::string openDevice();
  void releaseDevice();
  size_t inFlight() const;

  Options opt_;
  libusb_context* ctx_ = nullptr;
  libusb_device_handle* handle_ = nullptr;
  int fd_ = -1;
  int interface_ = -1;
  uint8_t ep_in_ = 0;
  uint8_t ep_out_ = 0;
  State state_ = State::kClosed;
  uint32_t generation_ = 0;
  Xfer in_[kInTransfers];
  Xfer out_[kOutTransfers];
  struct Body {
    uint8_t data[kInBufferBytes];
    size_t len;
  };
  Body ring_[kRxRing] = {};
  UsbOutQueue out_queue_;
  size_t ring_head_ = 0;
  size_t ring_len_ = 0;
  static constexpr size_t kMaxPollFds = 8;
  struct WaitFd {
    int fd;
    short events;
  };
  WaitFd poll_fds_[kMaxPollFds] = {};
  size_t poll_fd_count_ = 0;
  bool poll_fds_stale_ = true;
  static void onPollFdsChanged(int fd, short events, void* self);
  static void onPollFdRemoved(int fd, void* self);
  hal::PacketRxStats rx_stats_;
  UsbLinkStats stats_;
  std::string error_;
  std::string where_;
};

/// Parse "usb:VID:PID[:SERIAL]" (VID and PID four hexadecimal digits). Returns an empty string or what is wrong.
std::string parseUsbDevice(const std::string& spec, UsbLink::Options& out);

}  // namespace phalanx::linux_hal
