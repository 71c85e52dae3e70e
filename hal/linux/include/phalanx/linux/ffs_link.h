#pragma once
/// The device end of the USB transport, for the simulated firmware: a FunctionFS function (Linux USB gadget,
/// docs/usb.md) with one vendor-specific interface, bulk OUT (host → device) and bulk IN (device → host), one
/// protocol message body per transfer — the same wire format UsbLink speaks on the host. Endpoint I/O uses kernel
/// AIO (libaio) so that several requests stay queued on each endpoint and the firmware tick never blocks; ep0
/// events (enable, disable, unbind, suspend) follow the USB connection: while not enabled, send() refuses and the
/// firmware's own command timeout takes the outputs to their safe state.
/// A host that has gone (its process ended with the device still configured) neither writes nor reads: once the
/// IN pool is full and nothing came from the host for kHostAbsentServices services, the pool's messages are
/// withdrawn and sends refused until the host writes again (the next session's Hello). So the next session's first
/// answers go out at once, not behind a pool of stale telemetry and into a pool without room (docs/usb.md).
#include <libaio.h>

#include <cstddef>
#include <cstdint>
#include <string>

#include "phalanx/hal/hal.h"

namespace phalanx::linux_hal {

struct FfsLinkStats {
  uint64_t tx_submitted = 0;       ///< IN requests queued
  uint64_t tx_completed = 0;       ///< IN requests the host read
  uint64_t tx_dropped_full = 0;    ///< messages refused: every IN request of the pool queued
  uint64_t tx_dropped_offline = 0; ///< messages refused: USB function not enabled (unplugged, unconfigured)
  uint64_t tx_failed = 0;          ///< IN requests that ended in an error (unplug mid-transfer)
  uint64_t tx_dropped_host_idle = 0;  ///< messages refused: no host write since an enable or since the host was found gone
  uint64_t tx_cancelled = 0;       ///< queued IN requests withdrawn when the host stopped reading (stale by then)
  uint64_t rx_transfers = 0;       ///< OUT requests completed with data
  uint64_t rx_overflow = 0;        ///< bodies dropped: receive ring full
  uint64_t enables = 0;            ///< FUNCTIONFS_ENABLE events (host configured the device)
  uint64_t disables = 0;           ///< FUNCTIONFS_DISABLE / UNBIND events
  uint64_t setup_stalled = 0;      ///< control requests to our interface (none defined): stalled
};

class FfsLink : public hal::PacketLink {
 public:
  FfsLink() = default;
  FfsLink(const FfsLink&) = delete;
  FfsLink& operator=(const FfsLink&) = delete;
  ~FfsLink() override;

  /// dir: a mounted FunctionFS instance (mount -t functionfs NAME DIR). Writes the descriptors and strings to
  /// DIR/ep0 and opens DIR/ep1 (bulk OUT) and DIR/ep2 (bulk IN). Returns an empty string or what went wrong.
  std::string open(const std::string& dir);
  void close();

  bool send(uint8_t msg_id, const uint8_t* payload, size_t len) override;
  bool receive(uint8_t& msg_id, uint8_t* payload, size_t& len) override;
  hal::PacketRxStats rxStats() const override { return rx_stats_; }
  /// Read ep0 events and reap completed requests, without waiting. Call once per tick.
  void service();

  bool online() const { return online_; }
  const FfsLinkStats& stats() const { return stats_; }

  static constexpr size_t kOutRequests = 32;  ///< OUT requests kept queued (see docs/usb.md)
  static constexpr size_t kInRequests = 64;   ///< IN request pool (see docs/usb.md)
  static constexpr size_t kBufferBytes = 512; ///< a high-speed max packet; OUT reads are rounded up to it
  static constexpr size_t kRxRing = 128;
  static constexpr uint32_t kHostAbsentServices = 250;  ///< 0.25 s at 1 kHz; a session writes every host cycle

 private:
  struct Req {
    iocb cb{};
    bool in_flight = false;
    bool is_in = false;
    bool cancelled = false;
    uint8_t buf[kBufferBytes] = {};
  };
  void submitReads();
  void handleEp0();
  void withdrawQueuedSends();

  int ep0_ = -1;
  int ep_out_ = -1;
  int ep_in_ = -1;
  io_context_t aio_ = nullptr;
  bool online_ = false;
  bool host_idle_ = true;  ///< no OUT data since the function was enabled or since the host was found gone
  uint32_t services_since_rx_ = 0;
  Req out_[kOutRequests];
  Req in_[kInRequests];
  struct Body {
    uint8_t data[kBufferBytes];
    size_t len;
  };
  Body ring_[kRxRing] = {};
  size_t ring_head_ = 0;
  size_t ring_len_ = 0;
  hal::PacketRxStats rx_stats_;
  FfsLinkStats stats_;
};

}  // namespace phalanx::linux_hal
