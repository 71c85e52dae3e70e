#pragma once
/// `phalanx update IMAGE --device DEV`: a firmware update over the device's own link (docs/firmware-update.md).
/// The image is checked as `phalanx flash` checks it, streamed in UpdateData chunks with a window of chunks in
/// flight (go-back-N from the device's next_offset), committed, and the board's handshake after its reset must
/// show the image's build id. A lost link is reopened and the update resumed from where the device got to; a
/// device that lost power restarts it (a new `phalanx update` resumes or restarts the same way).
#include <cstddef>
#include <cstdint>
#include <string>

#include "phalanx/host/daemon.h"
#include "phalanx/image_info.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::host::update {

struct Request {
  std::string image_path;
  RunOptions link;            ///< link.device names the device (sim:, serial:, can:, usb:)
  image::BoardId board = image::BoardId::kStm32g474;  ///< the board the image must be linked for
  double timeout_s = 5.0;     ///< handshake, and silence that counts as a lost link
  unsigned reconnects = 3;    ///< lost links reopened before giving up
  unsigned window = 8;        ///< chunks in flight
  bool force = false;         ///< update even when the device already runs the image's build
  bool dry_run = false;       ///< check the image and handshake; write nothing
  bool no_confirm = false;    ///< leave the new image on trial (the board's next reset goes back to the old one)
};

/// Exit codes besides 0 and cli::kExitBadArguments (2); the same meanings as `phalanx flash`'s.
constexpr int kExitImageRefused = 3;  ///< the image failed a check (here or on the device): nothing was written
constexpr int kExitUpdateFailed = 4;  ///< the transfer or the commit failed (the board still boots its old image)
constexpr int kExitVerifyFailed = 5;  ///< committed, but the board's handshake after its reset shows another build
constexpr int kExitNoDevice = 6;      ///< the device cannot be opened or does not answer

/// "ok", "committed", "busy: …", … for messages.
std::string resultName(protocol::UpdateResult r, uint8_t detail = 0);

int run(const Request& request);

}  // namespace phalanx::host::update
