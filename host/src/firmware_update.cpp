#include "phalanx/host/firmware_update.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <vector>

#include "phalanx/host/device_link.h"
#include "phalanx/host/flash.h"
#include "phalanx/host/session.h"
#include "phalanx/linux/realtime.h"
#include "phalanx/protocol/devices.h"

namespace phalanx::host::update {

using protocol::MsgId;
using protocol::UpdateResult;
using protocol::UpdateStatus;

namespace {

constexpr uint64_t kMs = 1000000ull;
constexpr uint64_t kResendAfterNs = 250 * kMs;  // no progress this long: resend from the device's next_offset
constexpr unsigned kMaxRestarts = 3;            // updates begun again after a flash or verify failure

std::string hex32(uint32_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "%08x", static_cast<unsigned>(v));
  return b;
}

/// What one attempt over one open link came to.
enum class Outcome { kDone, kLinkLost, kRestart, kFailed, kRefused };

class Updater {
 public:
  Updater(const Request& r, std::vector<uint8_t> bytes, const image::ImageInfo& info)
      : r_(r), bytes_(std::move(bytes)), info_(info) {}

  int run() {
    if (std::string err = connect(); !err.empty()) return fail(refused_ ? kExitImageRefused : kExitNoDevice, err);
    const uint32_t running = session_->deviceInfo().firmware_build_id;
    const char* device = protocol::layoutFor(static_cast<protocol::DeviceType>(info_.device_type))->name;
    if (running == info_.build_id && !r_.force) {
      std::printf("%s on %s already runs build %s: nothing to do (--force updates anyway)\n", device,
                  link_->where().c_str(), hex32(running).c_str());
      return 0;
    }
    if (r_.dry_run) {
      std::printf("would update %s on %s from build %s to build %s (%u bytes in %zu-byte chunks)\n", device,
                  link_->where().c_str(), hex32(running).c_str(), hex32(info_.build_id).c_str(), info_.image_size,
                  protocol::kUpdateChunkBytes);
      return 0;
    }
    const uint64_t t0 = linux_hal::monotonicNs();
    unsigned reconnects = 0, restarts = 0;
    for (;;) {
      const Outcome o = attempt();
      if (o == Outcome::kDone) break;
      if (o == Outcome::kRefused) return fail(kExitImageRefused, error_);
      if (o == Outcome::kFailed) return fail(kExitUpdateFailed, error_ + " (the board still boots its previous image)");
      if (o == Outcome::kRestart) {
        if (++restarts > kMaxRestarts) return fail(kExitUpdateFailed, error_ + ", " + std::to_string(kMaxRestarts) +
                                                                       " times (the board still boots its previous image)");
        std::fprintf(stderr, "phalanx update: %s: beginning again\n", error_.c_str());
        continue;
      }
      // The link was lost: reopen it and resume.
      std::fprintf(stderr, "phalanx update: %s\n", error_.c_str());
      std::string err = "no reconnects left (--reconnects " + std::to_string(r_.reconnects) + ")";
      bool reopened = false;
      while (!reopened && reconnects < r_.reconnects) {
        ++reconnects;
        usleep(500000);
        err = connect();
        reopened = err.empty();
        if (!reopened) std::fprintf(stderr, "phalanx update: reconnect %u of %u: %s\n", reconnects, r_.reconnects, err.c_str());
      }
      if (!reopened) {
        return fail(kExitUpdateFailed, "the link was lost and not reopened (" + err +
                                           "); run the update again: it resumes or restarts, and the board boots a "
                                           "valid image meanwhile");
      }
    }
    const double seconds = static_cast<double>(linux_hal::monotonicNs() - t0) * 1e-9;
    // The board resets into the new image: a new session, whose handshake must show its build id.
    session_ = std::make_unique<HostSession>(link_->makeSession());
    if (std::string err = handshakeDevice(*link_, *session_, r_.timeout_s); !err.empty()) {
      return fail(kExitVerifyFailed, "committed, but after its reset: " + err);
    }
    const uint32_t now_running = session_->deviceInfo().firmware_build_id;
    if (now_running != info_.build_id) {
      return fail(kExitVerifyFailed, "committed, but the board came back with build " + hex32(now_running) +
                                         ", not the image's " + hex32(info_.build_id) +
                                         " (its boot stage did not accept the new image: it kept the old one)");
    }
    // The boot stage runs a new image on trial (docs/firmware-update.md "Trial boot"): it answered, so confirm it.
    std::string trial = "confirmed";
    if (r_.no_confirm) {
      trial = "on trial: not confirmed (--no-confirm): the board's next reset goes back to build " + hex32(running);
    } else if (std::string err = confirm(); !err.empty()) {
      return fail(kExitVerifyFailed, "build " + hex32(now_running) + " runs but is not confirmed (" + err +
                                         "): the board's next reset goes back to build " + hex32(running));
    }
    std::printf("updated %s on %s from build %s to build %s, %s: %u bytes in %.2f s (resent %u chunks, %u reconnects, "
                "%u restarts%s)\n",
                device, link_->where().c_str(), hex32(running).c_str(), hex32(now_running).c_str(), trial.c_str(),
                info_.image_size,
                seconds, resent_, reconnects, restarts,
                resumed_from_ > 0 ? (", resumed at byte " + std::to_string(resumed_from_)).c_str() : "");
    link_->close();
    return 0;
  }

 private:
  int fail(int rc, const std::string& what) {
    std::fprintf(stderr, "phalanx update: error: %s\n", what.c_str());
    if (link_) link_->close();
    return rc;
  }

  std::string connect() {
    if (link_) link_->close();
    session_.reset();
    std::string error;
    link_ = openDeviceLink(r_.link, error);
    if (!link_) return error;
    session_ = std::make_unique<HostSession>(link_->makeSession());
    if (std::string err = handshakeDevice(*link_, *session_, r_.timeout_s); !err.empty()) return err;
    const auto type = session_->deviceInfo().device_type;
    if (static_cast<uint8_t>(type) != info_.device_type) {
      refused_ = true;
      return std::string("the image is for a ") +
             protocol::layoutFor(static_cast<protocol::DeviceType>(info_.device_type))->name + ", the device on " +
             link_->where() + " is a " + protocol::layoutFor(type)->name + ": nothing was written";
    }
    return {};
  }

  /// Polls until a status answering `what` arrives (statuses of chunks are passed over); false after the timeout.
  bool await(MsgId what, UpdateStatus& st) {
    const uint64_t t0 = linux_hal::monotonicNs();
    while (linux_hal::monotonicNs() - t0 < static_cast<uint64_t>(r_.timeout_s * 1e9)) {
      session_->poll(linux_hal::monotonicNs());
      while (session_->popUpdateStatus(st)) {
        if (st.answers == what) return true;
      }
      if (!link_->deviceGone().empty()) return false;
      usleep(500);
    }
    return false;
  }

  /// Confirms the image the board runs on trial (core_param::kUpdateTrial = 1). "" when confirmed, or when the
  /// firmware has no trial boot (the parameter is unknown to it: nothing to confirm).
  std::string confirm() {
    const uint16_t id = protocol::core_param::kUpdateTrial;
    if (!session_->sendParamSet(id, 1.0f) || !link_->push()) return "the confirm could not be sent";
    const uint64_t t0 = linux_hal::monotonicNs();
    while (linux_hal::monotonicNs() - t0 < static_cast<uint64_t>(r_.timeout_s * 1e9)) {
      session_->poll(linux_hal::monotonicNs());
      if (session_->lastParamValid() && session_->lastParam().param_id == id) {
        const protocol::ParamStatus st = session_->lastParam().status;
        if (st == protocol::ParamStatus::kOk || st == protocol::ParamStatus::kUnknownParam) return {};
        return "the device answered the confirm with status " + std::to_string(static_cast<int>(st));
      }
      if (!link_->deviceGone().empty()) return "the link was lost before the confirm was answered";
      usleep(500);
    }
    return "no answer to the confirm within " + std::to_string(r_.timeout_s) + " s";
  }

  Outcome lost(const std::string& what) {
    error_ = "link lost " + what + " (no answer from the device on " + link_->where() + ")";
    return Outcome::kLinkLost;
  }

  /// Begin (or resume), stream, commit, over the open link.
  Outcome attempt() {
    const protocol::UpdateBegin b = image::updateBeginFor(info_);
    UpdateStatus st;
    if (!session_->sendUpdate(b) || !link_->push() || !await(MsgId::kUpdateBegin, st)) return lost("at the begin");
    if (st.result == UpdateResult::kBadImage) {
      error_ = "the device refused the image: " + resultName(st.result, st.detail) + ": nothing was written";
      return Outcome::kRefused;
    }
    if (st.result != UpdateResult::kOk) {
      error_ = "the device refused the update: " + resultName(st.result, st.detail);
      return Outcome::kFailed;
    }
    if (st.next_offset > 0) {
      resumed_from_ = st.next_offset;
      std::fprintf(stderr, "phalanx update: resuming at byte %u of %u (slot %u)\n", st.next_offset, info_.image_size,
                   st.slot);
    } else {
      std::fprintf(stderr, "phalanx update: writing %u bytes into slot %u\n", info_.image_size, st.slot);
    }
    if (const Outcome o = stream(st.next_offset); o != Outcome::kDone) return o;
    protocol::UpdateCommit c;
    c.image_crc32 = info_.image_crc32;
    c.build_id = info_.build_id;
    if (!session_->sendUpdate(c) || !link_->push() || !await(MsgId::kUpdateCommit, st)) return lost("at the commit");
    if (st.result == UpdateResult::kCommitted) return Outcome::kDone;
    error_ = "commit: " + resultName(st.result, st.detail);
    return st.result == UpdateResult::kVerifyFailed || st.result == UpdateResult::kFlashError ||
                   st.result == UpdateResult::kNotStarted
               ? Outcome::kRestart
               : Outcome::kFailed;
  }

  static unsigned chunksBetween(uint32_t from, uint32_t to) {
    return (to - from + static_cast<unsigned>(protocol::kUpdateChunkBytes) - 1u) / static_cast<unsigned>(protocol::kUpdateChunkBytes);
  }

  void sendChunk(uint32_t at) {
    protocol::UpdateData d;
    d.offset = at;
    const size_t n = std::min<size_t>(protocol::kUpdateChunkBytes, info_.image_size - at);
    d.length = static_cast<uint8_t>(n);
    std::copy_n(bytes_.begin() + at, n, d.data);
    session_->sendUpdate(d);
  }

  /// Chunks from `acked` (the device's next_offset) to the end, `window` in flight, go-back-N on a gap or silence.
  Outcome stream(uint32_t acked) {
    const uint32_t size = info_.image_size;
    const uint32_t window = r_.window * static_cast<uint32_t>(protocol::kUpdateChunkBytes);
    uint32_t next = acked, rewound_to = UINT32_MAX, shown = acked * 10 / size;
    uint64_t progress_ns = linux_hal::monotonicNs(), quiet_since = progress_ns;
    while (acked < size) {
      while (next < size && next - acked < window) {
        sendChunk(next);
        next += static_cast<uint32_t>(std::min<size_t>(protocol::kUpdateChunkBytes, size - next));
      }
      if (!link_->push()) return lost("while sending: " + link_->linkError());
      const uint64_t now = linux_hal::monotonicNs();
      session_->poll(now);
      UpdateStatus st;
      while (session_->popUpdateStatus(st)) {
        if (st.answers != MsgId::kUpdateData) continue;
        if (st.result == UpdateResult::kOk || st.result == UpdateResult::kOutOfOrder) {
          if (st.next_offset > acked) {
            acked = st.next_offset;
            progress_ns = now;
          }
          // A gap (a chunk lost on the way): send again from where the device is, once per gap.
          if (st.result == UpdateResult::kOutOfOrder && st.next_offset != rewound_to && st.next_offset < next) {
            resent_ += chunksBetween(st.next_offset, next);
            next = rewound_to = st.next_offset;
          }
          continue;
        }
        error_ = "after byte " + std::to_string(acked) + ": " + resultName(st.result, st.detail);
        return st.result == UpdateResult::kBadChunk ? Outcome::kFailed : Outcome::kRestart;
      }
      if (acked * 10 / size != shown) {
        shown = acked * 10 / size;
        std::fprintf(stderr, "phalanx update: %u%%\n", shown * 10);
      }
      if (!link_->deviceGone().empty()) return lost("while sending: " + link_->deviceGone());
      if (now - progress_ns > static_cast<uint64_t>(r_.timeout_s * 1e9)) return lost("while sending");
      if (now - std::max(progress_ns, quiet_since) > kResendAfterNs && next > acked) {
        resent_ += chunksBetween(acked, next);
        next = rewound_to = acked;  // silence: the window's chunks (or their answers) were lost
        quiet_since = now;
      }
      usleep(200);
    }
    return Outcome::kDone;
  }

  const Request& r_;
  std::vector<uint8_t> bytes_;
  image::ImageInfo info_;
  std::unique_ptr<DeviceLink> link_;
  std::unique_ptr<HostSession> session_;
  std::string error_;
  bool refused_ = false;
  unsigned resent_ = 0;
  uint32_t resumed_from_ = 0;
};

}  // namespace

std::string resultName(UpdateResult r, uint8_t detail) {
  switch (r) {
    case UpdateResult::kOk: return "ok";
    case UpdateResult::kCommitted: return "committed";
    case UpdateResult::kBusy: return "busy: the device's outputs are active (stop the motion first)";
    case UpdateResult::kBadImage: {
      static const char* const kField[] = {"?", "device type", "board", "size (too small, or larger than a slot)",
                                           "build id 0", "reserved field not 0", "session id (another host's)"};
      return std::string("not for this board: ") + (detail < 7 ? kField[detail] : "?");
    }
    case UpdateResult::kNotStarted: return "no update begun on the device (it reset, or a failure ended it)";
    case UpdateResult::kOutOfOrder: return "out of order";
    case UpdateResult::kBadChunk: return "chunk refused (offset, length or padding)";
    case UpdateResult::kFlashError: return "flash erase/program failed on the device";
    case UpdateResult::kVerifyFailed: return "the received image did not verify (CRC or image-info block)";
    case UpdateResult::kNoUpdater: return "this board cannot be updated over its link";
    case UpdateResult::kUnconfirmed:
      return "the board runs an image on trial, not yet confirmed: confirm it (phalanx param set update_trial 1) or "
             "reset the board to go back to its previous image, then update";
  }
  return "unknown result";
}

int run(const Request& request) {
  std::vector<uint8_t> bytes;
  std::string error;
  if (!flash::readImageFile(request.image_path, bytes, error)) {
    std::fprintf(stderr, "phalanx update: error: %s\n", error.c_str());
    return kExitImageRefused;
  }
  flash::Expectation expect;
  expect.board = request.board;
  flash::CheckedImage image;
  if (std::string err = flash::checkImage(bytes, expect, image); !err.empty()) {
    std::fprintf(stderr, "phalanx update: error: %s: %s: nothing was written\n", request.image_path.c_str(), err.c_str());
    return kExitImageRefused;
  }
  Updater u(request, std::move(image.bytes), image.info);
  return u.run();
}

}  // namespace phalanx::host::update
