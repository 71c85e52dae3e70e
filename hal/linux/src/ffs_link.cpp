#include "phalanx/linux/ffs_link.h"

#include "phalanx/linux/packet_body.h"

#include <endian.h>
#include <fcntl.h>
#include <linux/usb/ch9.h>
#include <linux/usb/functionfs.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>

#include "phalanx/protocol/codec.h"

namespace phalanx::linux_hal {
namespace {

struct __attribute__((packed)) InterfaceDescs {
  usb_interface_descriptor intf;
  usb_endpoint_descriptor_no_audio out;
  usb_endpoint_descriptor_no_audio in;
};

struct __attribute__((packed)) Descriptors {
  usb_functionfs_descs_head_v2 header;
  uint32_t fs_count;
  uint32_t hs_count;
  InterfaceDescs fs;
  InterfaceDescs hs;
};

constexpr char kInterfaceName[] = "Phalanx";

struct __attribute__((packed)) Strings {
  usb_functionfs_strings_head header;
  uint16_t lang;
  char str[sizeof kInterfaceName];
};

InterfaceDescs interfaceDescs(uint16_t max_packet) {
  InterfaceDescs d{};
  d.intf.bLength = sizeof d.intf;
  d.intf.bDescriptorType = USB_DT_INTERFACE;
  d.intf.bNumEndpoints = 2;
  d.intf.bInterfaceClass = USB_CLASS_VENDOR_SPEC;
  d.intf.iInterface = 1;
  d.out.bLength = sizeof d.out;
  d.out.bDescriptorType = USB_DT_ENDPOINT;
  d.out.bEndpointAddress = 1 | USB_DIR_OUT;
  d.out.bmAttributes = USB_ENDPOINT_XFER_BULK;
  d.out.wMaxPacketSize = htole16(max_packet);
  d.in = d.out;
  d.in.bEndpointAddress = 2 | USB_DIR_IN;
  return d;
}

// No protocol body is a whole number of max packets (largest 67 bytes; full speed 64, high speed 512), so every
// body ends in a short packet and the host's transfer completes with exactly one body, without zero-length packets.
// send() refuses a 64-byte body (no message has one: it would need a zero-length packet at full speed).
static_assert(protocol::kMaxFrameBody < 128, "a body longer than two full-speed packets: check the ZLP rule");

}  // namespace

FfsLink::~FfsLink() { close(); }

void FfsLink::close() {
  if (aio_ != nullptr) {
    io_event ev[kOutRequests + kInRequests];
    for (auto* set : {static_cast<Req*>(out_), static_cast<Req*>(in_)}) {
      const size_t n = set == out_ ? kOutRequests : kInRequests;
      for (size_t i = 0; i < n; ++i) {
        if (set[i].in_flight) io_cancel(aio_, &set[i].cb, ev);
      }
    }
    io_destroy(aio_);
    aio_ = nullptr;
  }
  for (int* fd : {&ep_in_, &ep_out_, &ep0_}) {
    if (*fd >= 0) ::close(*fd);
    *fd = -1;
  }
  online_ = false;
}

std::string FfsLink::open(const std::string& dir) {
  close();
  auto fail = [&](const std::string& what) {
    const std::string e = what + ": " + std::strerror(errno);
    close();
    return e;
  };
  ep0_ = ::open((dir + "/ep0").c_str(), O_RDWR | O_CLOEXEC);
  if (ep0_ < 0) return fail("cannot open " + dir + "/ep0 (is a FunctionFS instance mounted there?)");
  Descriptors d{};
  d.header.magic = htole32(FUNCTIONFS_DESCRIPTORS_MAGIC_V2);
  d.header.length = htole32(sizeof d);
  d.header.flags = htole32(FUNCTIONFS_HAS_FS_DESC | FUNCTIONFS_HAS_HS_DESC);
  d.fs_count = htole32(3);
  d.hs_count = htole32(3);
  d.fs = interfaceDescs(64);
  d.hs = interfaceDescs(512);
  if (::write(ep0_, &d, sizeof d) != static_cast<ssize_t>(sizeof d)) return fail("writing USB descriptors to " + dir + "/ep0");
  Strings s{};
  s.header.magic = htole32(FUNCTIONFS_STRINGS_MAGIC);
  s.header.length = htole32(sizeof s);
  s.header.str_count = htole32(1);
  s.header.lang_count = htole32(1);
  s.lang = htole16(0x0409);
  std::memcpy(s.str, kInterfaceName, sizeof kInterfaceName);
  if (::write(ep0_, &s, sizeof s) != static_cast<ssize_t>(sizeof s)) return fail("writing USB strings to " + dir + "/ep0");
  // Endpoint files appear once the descriptors are accepted. Non-blocking: an AIO submit on an endpoint that is
  // not enabled then fails with EAGAIN instead of waiting for the host.
  ep_out_ = ::open((dir + "/ep1").c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (ep_out_ < 0) return fail("cannot open " + dir + "/ep1");
  ep_in_ = ::open((dir + "/ep2").c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (ep_in_ < 0) return fail("cannot open " + dir + "/ep2");
  if (fcntl(ep0_, F_SETFL, O_NONBLOCK) != 0) return fail("fcntl ep0");
  if (const int rc = io_setup(static_cast<int>(kOutRequests + kInRequests), &aio_); rc != 0) {
    errno = -rc;
    aio_ = nullptr;
    return fail("io_setup");
  }
  for (auto& r : in_) r.is_in = true;
  return {};
}

void FfsLink::submitReads() {
  for (auto& r : out_) {
    if (r.in_flight) continue;
    io_prep_pread(&r.cb, ep_out_, r.buf, kBufferBytes, 0);
    r.cb.data = &r;
    iocb* p = &r.cb;
    if (io_submit(aio_, 1, &p) != 1) return;  // -EAGAIN: the endpoint is not enabled (yet)
    r.in_flight = true;
  }
}

void FfsLink::handleEp0() {
  usb_functionfs_event ev[4];
  for (;;) {
    const ssize_t n = ::read(ep0_, ev, sizeof ev);
    if (n <= 0) return;
    for (size_t i = 0; i < static_cast<size_t>(n) / sizeof ev[0]; ++i) {
      switch (ev[i].type) {
        case FUNCTIONFS_ENABLE:
          online_ = true;
          host_idle_ = true;  // (re)configured: nothing is sent before the host has written
          ++stats_.enables;
          break;
        case FUNCTIONFS_DISABLE:
        case FUNCTIONFS_UNBIND:
        case FUNCTIONFS_SUSPEND:
          if (online_) ++stats_.disables;
          online_ = false;
          break;
        case FUNCTIONFS_SETUP: {
          // No control requests are defined for the interface: stall (read for IN requests, write for OUT).
          ++stats_.setup_stalled;
          uint8_t dummy = 0;
          if (ev[i].u.setup.bRequestType & USB_DIR_IN) {
            (void)!::read(ep0_, &dummy, 0);
          } else {
            (void)!::write(ep0_, &dummy, 0);
          }
          break;
        }
        case FUNCTIONFS_RESUME:
          online_ = true;
          break;
        default:
          break;
      }
    }
  }
}

void FfsLink::service() {
  if (aio_ == nullptr) return;
  if (services_since_rx_ < kHostAbsentServices) ++services_since_rx_;
  handleEp0();
  io_event ev[kOutRequests + kInRequests];
  timespec zero{0, 0};
  const int n = io_getevents(aio_, 0, static_cast<long>(kOutRequests + kInRequests), ev, &zero);
  for (int i = 0; i < n; ++i) {
    Req& r = *static_cast<Req*>(ev[i].data);
    r.in_flight = false;
    const long res = static_cast<long>(ev[i].res);
    if (r.is_in) {
      if (res > 0) {
        ++stats_.tx_completed;
      } else if (r.cancelled) {
        ++stats_.tx_cancelled;
      } else {
        ++stats_.tx_failed;
      }
      r.cancelled = false;
      continue;
    }
    if (res <= 0) continue;  // ESHUTDOWN on disable: resubmitted once enabled again
    ++stats_.rx_transfers;
    host_idle_ = false;
    services_since_rx_ = 0;
    if (ring_len_ == kRxRing) {
      ++stats_.rx_overflow;
      ring_head_ = (ring_head_ + 1) % kRxRing;
      --ring_len_;
    }
    Body& b = ring_[(ring_head_ + ring_len_) % kRxRing];
    b.len = static_cast<size_t>(res) < kBufferBytes ? static_cast<size_t>(res) : kBufferBytes;
    std::memcpy(b.data, r.buf, b.len);
    ++ring_len_;
  }
  if (online_) submitReads();
}

bool FfsLink::send(uint8_t msg_id, const uint8_t* payload, size_t len) {
  if (!online_) {
    ++stats_.tx_dropped_offline;
    return false;
  }
  if (len > protocol::kMaxPayload || len + 3 == 64) return false;
  if (host_idle_) {
    ++stats_.tx_dropped_host_idle;
    return false;
  }
  Req* slot = nullptr;
  for (auto& r : in_) {
    if (!r.in_flight) {
      slot = &r;
      break;
    }
  }
  if (slot == nullptr) {
    ++stats_.tx_dropped_full;
    if (services_since_rx_ >= kHostAbsentServices) withdrawQueuedSends();
    return false;
  }
  slot->buf[0] = msg_id;
  std::memcpy(slot->buf + 1, payload, len);
  const uint16_t crc = protocol::crc16(slot->buf, len + 1);
  slot->buf[len + 1] = static_cast<uint8_t>(crc & 0xFF);
  slot->buf[len + 2] = static_cast<uint8_t>(crc >> 8);
  io_prep_pwrite(&slot->cb, ep_in_, slot->buf, len + 3, 0);
  slot->cb.data = slot;
  iocb* p = &slot->cb;
  if (io_submit(aio_, 1, &p) != 1) {
    ++stats_.tx_dropped_offline;  // EAGAIN: disabled between the last ep0 event and now
    return false;
  }
  slot->in_flight = true;
  ++stats_.tx_submitted;
  return true;
}

void FfsLink::withdrawQueuedSends() {
  // Every IN request queued and nothing written by the host for kHostAbsentServices: the host has gone. What the
  // pool holds is stale by the time a host reads again, and would hold the next session's HelloAck behind it;
  // withdraw it (FunctionFS dequeues the request; its completion, an error, may come through io_getevents) and
  // refuse sends until the host writes.
  host_idle_ = true;
  for (auto& r : in_) {
    if (!r.in_flight || r.cancelled) continue;
    io_event ev{};
    r.cancelled = true;
    if (io_cancel(aio_, &r.cb, &ev) == 0) {  // completed here rather than through io_getevents
      r.in_flight = false;
      r.cancelled = false;
      ++stats_.tx_cancelled;
    }
  }
}

bool FfsLink::receive(uint8_t& msg_id, uint8_t* payload, size_t& len) {
  while (ring_len_ > 0) {
    const Body& b = ring_[ring_head_];
    ring_head_ = (ring_head_ + 1) % kRxRing;
    --ring_len_;
    if (acceptBody(b.data, b.len, rx_stats_, msg_id, payload, len)) return true;
  }
  return false;
}

}  // namespace phalanx::linux_hal
