#include "phalanx/linux/usb_link.h"

#include "phalanx/linux/packet_body.h"

#include <dirent.h>
#include <fcntl.h>
#include <libusb-1.0/libusb.h>
#include <poll.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>

#include "phalanx/protocol/codec.h"

namespace phalanx::linux_hal {
namespace {

std::string readAttr(const std::string& path) {
  std::ifstream f(path);
  std::string s;
  std::getline(f, s);
  return s;
}

bool parseHex16(const std::string& s, uint16_t& out) {
  // Exactly four hexadecimal digits: strtoul alone would also take a sign or leading blanks ("-001").
  if (s.size() != 4) return false;
  uint16_t v = 0;
  for (const char c : s) {
    if (std::isxdigit(static_cast<unsigned char>(c)) == 0) return false;
    v = static_cast<uint16_t>(v * 16 + static_cast<uint16_t>(std::isdigit(static_cast<unsigned char>(c)) != 0
                                                                  ? c - '0'
                                                                  : std::tolower(static_cast<unsigned char>(c)) - 'a' + 10));
  }
  out = v;
  return true;
}

/// The sysfs device (e.g. "1-1") whose idVendor/idProduct (and serial, if asked) match; empty when none.
std::string findInSysfs(const UsbLink::Options& opt, int& bus, int& addr) {
  DIR* d = opendir("/sys/bus/usb/devices");
  if (d == nullptr) return {};
  std::string found;
  while (dirent* e = readdir(d)) {
    const std::string name = e->d_name;
    if (name.empty() || name[0] == '.' || name.find(':') != std::string::npos) continue;  // interfaces
    const std::string base = "/sys/bus/usb/devices/" + name + "/";
    uint16_t vid = 0, pid = 0;
    if (!parseHex16(readAttr(base + "idVendor"), vid) || !parseHex16(readAttr(base + "idProduct"), pid)) continue;
    if (vid != opt.vid || pid != opt.pid) continue;
    if (!opt.serial.empty() && readAttr(base + "serial") != opt.serial) continue;
    bus = std::atoi(readAttr(base + "busnum").c_str());
    addr = std::atoi(readAttr(base + "devnum").c_str());
    if (bus <= 0 || addr <= 0) continue;
    found = name;
    break;
  }
  closedir(d);
  return found;
}

}  // namespace

std::string parseUsbDevice(const std::string& spec, UsbLink::Options& out) {
  if (spec.rfind("usb:", 0) != 0) return "not a USB device";
  const std::string rest = spec.substr(4);
  out = UsbLink::Options{};
  const auto c1 = rest.find(':');
  if (c1 == std::string::npos) return "device: '" + spec + "': expected usb:VID:PID[:SERIAL] (hexadecimal, e.g. usb:1209:0001)";
  const auto c2 = rest.find(':', c1 + 1);
  const std::string vid = rest.substr(0, c1);
  const std::string pid = c2 == std::string::npos ? rest.substr(c1 + 1) : rest.substr(c1 + 1, c2 - c1 - 1);
  if (!parseHex16(vid, out.vid)) return "device: '" + spec + "': vendor id '" + vid + "' is not four hexadecimal digits";
  if (!parseHex16(pid, out.pid)) return "device: '" + spec + "': product id '" + pid + "' is not four hexadecimal digits";
  if (c2 != std::string::npos) {
    out.serial = rest.substr(c2 + 1);
    if (out.serial.empty() || out.serial.size() > 126) return "device: '" + spec + "': empty or too long serial number";
  }
  return {};
}

UsbLink::~UsbLink() { close(); }

std::string UsbLink::open(const Options& opt) {
  close();
  opt_ = opt;
  // Discovery is ours (sysfs): libusb's own device list follows udev, which a minimal system or container lacks.
  libusb_set_option(nullptr, LIBUSB_OPTION_NO_DEVICE_DISCOVERY);
  if (const int rc = libusb_init(&ctx_); rc != 0) {
    ctx_ = nullptr;
    return std::string("libusb_init: ") + libusb_error_name(rc);
  }
  poll_fds_stale_ = true;
  libusb_set_pollfd_notifiers(ctx_, &UsbLink::onPollFdsChanged, &UsbLink::onPollFdRemoved, this);
  for (auto& x : in_) {
    x.t = libusb_alloc_transfer(0);
    x.link = this;
    x.is_in = true;
  }
  for (auto& x : out_) {
    x.t = libusb_alloc_transfer(0);
    x.link = this;
  }
  return openDevice();
}

std::string UsbLink::openDevice() {
  int bus = 0, addr = 0;
  const std::string where = findInSysfs(opt_, bus, addr);
  char id[16];
  std::snprintf(id, sizeof id, "%04x:%04x", opt_.vid, opt_.pid);
  if (where.empty()) {
    return std::string("no USB device ") + id + (opt_.serial.empty() ? "" : " with serial " + opt_.serial) +
           " (lsusb lists what is connected)";
  }
  char node[64];
  std::snprintf(node, sizeof node, "/dev/bus/usb/%03d/%03d", bus, addr);
  fd_ = ::open(node, O_RDWR | O_CLOEXEC);
  if (fd_ < 0) return std::string("cannot open ") + node + ": " + std::strerror(errno) + " (permissions: a udev rule, or run as root)";
  if (const int rc = libusb_wrap_sys_device(ctx_, static_cast<intptr_t>(fd_), &handle_); rc != 0) {
    ::close(fd_);
    fd_ = -1;
    handle_ = nullptr;
    return std::string("libusb_wrap_sys_device ") + node + ": " + libusb_error_name(rc);
  }
  // The vendor-specific interface with one bulk IN and one bulk OUT endpoint.
  libusb_config_descriptor* cfg = nullptr;
  if (const int rc = libusb_get_active_config_descriptor(libusb_get_device(handle_), &cfg); rc != 0) {
    releaseDevice();
    return std::string("reading the configuration of ") + id + ": " + libusb_error_name(rc);
  }
  interface_ = -1;
  for (uint8_t i = 0; i < cfg->bNumInterfaces && interface_ < 0; ++i) {
    if (cfg->interface[i].num_altsetting < 1) continue;
    const libusb_interface_descriptor& d = cfg->interface[i].altsetting[0];
    if (d.bInterfaceClass != LIBUSB_CLASS_VENDOR_SPEC) continue;
    uint8_t in = 0, out = 0;
    for (uint8_t e = 0; e < d.bNumEndpoints; ++e) {
      const libusb_endpoint_descriptor& ep = d.endpoint[e];
      if ((ep.bmAttributes & 0x3) != LIBUSB_TRANSFER_TYPE_BULK) continue;
      if (ep.bEndpointAddress & LIBUSB_ENDPOINT_IN) {
        in = ep.bEndpointAddress;
      } else {
        out = ep.bEndpointAddress;
      }
    }
    if (in != 0 && out != 0) {
      interface_ = d.bInterfaceNumber;
      ep_in_ = in;
      ep_out_ = out;
    }
  }
  libusb_free_config_descriptor(cfg);
  if (interface_ < 0) {
    releaseDevice();
    return std::string("USB device ") + id + " has no vendor-specific interface with bulk IN and OUT endpoints";
  }
  libusb_set_auto_detach_kernel_driver(handle_, 1);
  if (const int rc = libusb_claim_interface(handle_, interface_); rc != 0) {
    releaseDevice();
    return std::string("cannot claim interface ") + std::to_string(interface_) + " of " + id + ": " + libusb_error_name(rc);
  }
  where_ = where + " (bus " + std::to_string(bus) + " address " + std::to_string(addr) + ")";
  state_ = State::kConnected;
  ring_len_ = 0;
  ring_head_ = 0;
  for (auto& x : in_) {
    if (!submitIn(x)) {
      lost("submitting IN transfers failed");
      return "USB device " + std::string(id) + ": " + error_;
    }
  }
  ++generation_;
  ++stats_.connects;
  error_.clear();
  return {};
}

bool UsbLink::submitIn(Xfer& x) {
  libusb_fill_bulk_transfer(x.t, handle_, ep_in_, x.buf, static_cast<int>(kInBufferBytes), &UsbLink::onTransfer, &x, 0);
  const int rc = libusb_submit_transfer(x.t);
  if (rc != 0) {
    error_ = std::string("IN submit: ") + libusb_error_name(rc);
    return false;
  }
  x.in_flight = true;
  return true;
}

void UsbLink::onTransfer(libusb_transfer* t) {
  Xfer& x = *static_cast<Xfer*>(t->user_data);
  x.link->complete(x);
}

void UsbLink::complete(Xfer& x) {
  x.in_flight = false;
  const libusb_transfer_status st = x.t->status;
  if (st == LIBUSB_TRANSFER_NO_DEVICE) {
    lost("device unplugged");
    return;
  }
  if (!x.is_in) {
    if (st == LIBUSB_TRANSFER_COMPLETED && x.t->actual_length == x.t->length) {
      ++stats_.tx_completed;
    } else if (st != LIBUSB_TRANSFER_CANCELLED) {
      ++stats_.tx_failed;
    }
    return;
  }
  if (st == LIBUSB_TRANSFER_COMPLETED) {
    ++stats_.rx_transfers;
    if (ring_len_ == kRxRing) {
      ++stats_.rx_overflow;  // the loop stopped reading: keep the newest, drop the oldest
      ring_head_ = (ring_head_ + 1) % kRxRing;
      --ring_len_;
    }
    Body& b = ring_[(ring_head_ + ring_len_) % kRxRing];
    b.len = static_cast<size_t>(x.t->actual_length);
    std::memcpy(b.data, x.buf, b.len);
    ++ring_len_;
  } else if (st != LIBUSB_TRANSFER_CANCELLED) {
    ++stats_.rx_failed;
    if (st == LIBUSB_TRANSFER_STALL) libusb_clear_halt(handle_, ep_in_);  // not expected from our device
  }
  if (state_ == State::kConnected && st != LIBUSB_TRANSFER_CANCELLED && !submitIn(x)) lost(error_.c_str());
}

void UsbLink::lost(const char* why) {
  if (state_ != State::kConnected) return;
  ++stats_.disconnects;
  error_ = why;
  state_ = State::kDraining;
  stats_.tx_discarded_unplug += out_queue_.clear();
  // Nothing queued before the unplug may go out afterwards: cancel everything; the callbacks return each one.
  for (auto& x : in_) {
    if (x.in_flight) libusb_cancel_transfer(x.t);
  }
  for (auto& x : out_) {
    if (x.in_flight) libusb_cancel_transfer(x.t);
  }
}

size_t UsbLink::inFlight() const {
  size_t n = 0;
  for (const auto& x : in_) n += x.in_flight;
  for (const auto& x : out_) n += x.in_flight;
  return n;
}

void UsbLink::releaseDevice() {
  if (handle_ != nullptr) {
    if (interface_ >= 0) libusb_release_interface(handle_, interface_);  // fails harmlessly once unplugged
    libusb_close(handle_);
  }
  handle_ = nullptr;
  if (fd_ >= 0) ::close(fd_);  // libusb does not close a wrapped descriptor
  fd_ = -1;
  interface_ = -1;
}

bool UsbLink::service() {
  if (ctx_ == nullptr) return false;
  timeval zero{0, 0};
  libusb_handle_events_timeout_completed(ctx_, &zero, nullptr);
  pumpOut();
  if (state_ == State::kDraining && inFlight() == 0) {
    releaseDevice();
    state_ = State::kClosed;
  }
  return state_ == State::kConnected;
}

void UsbLink::onPollFdsChanged(int, short, void* self) { static_cast<UsbLink*>(self)->poll_fds_stale_ = true; }
void UsbLink::onPollFdRemoved(int, void* self) { static_cast<UsbLink*>(self)->poll_fds_stale_ = true; }

size_t UsbLink::pollFds(pollfd* fds, size_t max) {
  if (ctx_ == nullptr) return 0;
  if (poll_fds_stale_) {
    // Allocates (libusb's list): only after libusb added or removed a descriptor (open, unplug, reconnect).
    poll_fd_count_ = 0;
    if (const libusb_pollfd** list = libusb_get_pollfds(ctx_); list != nullptr) {
      for (size_t i = 0; list[i] != nullptr && poll_fd_count_ < kMaxPollFds; ++i) {
        poll_fds_[poll_fd_count_++] = {list[i]->fd, list[i]->events};
      }
      libusb_free_pollfds(list);
    }
    poll_fds_stale_ = false;
  }
  size_t n = 0;
  for (; n < poll_fd_count_ && n < max; ++n) fds[n] = {poll_fds_[n].fd, poll_fds_[n].events, 0};
  return n;
}

std::string UsbLink::reconnect() {
  if (ctx_ == nullptr) return "USB link was never opened";
  service();
  if (state_ == State::kConnected) return {};
  if (state_ == State::kDraining) return "still returning the transfers of the unplugged device";
  ++stats_.reconnect_attempts;
  return openDevice();
}

void UsbLink::close() {
  if (ctx_ == nullptr) return;
  if (state_ == State::kConnected) {
    lost("closed");
    --stats_.disconnects;
  }
  // Bounded: every cancelled transfer returns within a few milliseconds; give up after 2 s rather than hang.
  for (int i = 0; i < 2000 && inFlight() > 0; ++i) {
    timeval ms{0, 1000};
    libusb_handle_events_timeout_completed(ctx_, &ms, nullptr);
  }
  releaseDevice();
  state_ = State::kClosed;
  libusb_set_pollfd_notifiers(ctx_, nullptr, nullptr, nullptr);  // a leaked context must not call back into us
  poll_fd_count_ = 0;
  poll_fds_stale_ = true;
  if (inFlight() == 0) {
    for (auto& x : in_) libusb_free_transfer(x.t);
    for (auto& x : out_) libusb_free_transfer(x.t);
    libusb_exit(ctx_);
  }  // else: leak the context rather than free transfers libusb still owns
  for (auto& x : in_) x.t = nullptr;
  for (auto& x : out_) x.t = nullptr;
  ctx_ = nullptr;
}

bool UsbLink::send(uint8_t msg_id, const uint8_t* payload, size_t len) {
  if (state_ != State::kConnected) {
    ++stats_.tx_dropped_offline;
    return false;
  }
  if (len > protocol::kMaxPayload) return false;
  uint8_t body[protocol::kMaxFrameBody];
  body[0] = msg_id;
  std::memcpy(body + 1, payload, len);
  const uint16_t crc = protocol::crc16(body, len + 1);
  body[len + 1] = static_cast<uint8_t>(crc & 0xFF);
  body[len + 2] = static_cast<uint8_t>(crc >> 8);
  // In order: straight to a free transfer only when nothing is held back.
  if (out_queue_.empty()) {
    const int r = submitOut(body, len + 3);
    if (r != 0) return r > 0;
  }
  // Every OUT transfer in flight: hold it back; a newer command replaces an older one still waiting here.
  const uint64_t before = out_queue_.superseded();
  if (out_queue_.push(msg_id, body, len + 3) == UsbOutQueue::Push::kFull) {
    ++stats_.tx_dropped_busy;
    return false;
  }
  stats_.tx_superseded += out_queue_.superseded() - before;
  ++stats_.tx_queued;
  return pumpOut();
}

int UsbLink::submitOut(const uint8_t* body, size_t len) {
  Xfer* slot = nullptr;
  for (auto& x : out_) {
    if (!x.in_flight) {
      slot = &x;
      break;
    }
  }
  if (slot == nullptr) return 0;
  std::memcpy(slot->buf, body, len);
  libusb_fill_bulk_transfer(slot->t, handle_, ep_out_, slot->buf, static_cast<int>(len), &UsbLink::onTransfer, slot, 0);
  const int rc = libusb_submit_transfer(slot->t);
  if (rc == LIBUSB_ERROR_NO_DEVICE) {
    lost("device unplugged");
    ++stats_.tx_dropped_offline;
    return -1;
  }
  if (rc != 0) {
    ++stats_.tx_failed;
    error_ = std::string("OUT submit: ") + libusb_error_name(rc);
    return -1;
  }
  slot->in_flight = true;
  ++stats_.tx_messages;
  return 1;
}

bool UsbLink::pumpOut() {
  while (state_ == State::kConnected && !out_queue_.empty()) {
    const UsbOutQueue::Body& b = out_queue_.front();
    const int r = submitOut(b.data, b.len);
    if (r == 0) break;
    out_queue_.pop();  // submitted, or failed and counted (a failed submit is not retried)
  }
  return state_ == State::kConnected;
}

bool UsbLink::receive(uint8_t& msg_id, uint8_t* payload, size_t& len) {
  if (ring_len_ == 0) service();
  while (ring_len_ > 0) {
    const Body& b = ring_[ring_head_];
    ring_head_ = (ring_head_ + 1) % kRxRing;
    --ring_len_;
    if (acceptBody(b.data, b.len, rx_stats_, msg_id, payload, len)) return true;
  }
  return false;
}

}  // namespace phalanx::linux_hal
