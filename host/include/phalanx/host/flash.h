#pragma once
/// `phalanx flash`: writing a whole firmware image into a board with the tools users have from Debian, after
/// checking the image, and checking the board afterwards (docs/firmware-mcu.md "Flashing").
///   openocd   ST-Link over SWD (the STM32G474): `openocd ... -c "program IMAGE ADDR verify reset exit"`
///   dfu       the STM32's ROM DFU bootloader over USB: `dfu-util -d 0483:df11 -a 0 -s ADDR:leave -D IMAGE`
///   gdb       a debugger stub, QEMU's gdbstub for the emulated boards: `gdb-multiarch -batch ... restore ...`
/// The image is the raw .bin of the cross build (phalanx-<board>-<app>.bin); its image-info block
/// (common/include/phalanx/image_info.h) says what it is. Nothing is written unless every check passes.
#include <cstdint>
#include <string>
#include <vector>

#include "phalanx/image_info.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::host::flash {

enum class Via { kGdb, kOpenocd, kDfu };

/// "gdb" | "openocd" | "dfu" → Via; false for anything else.
bool parseVia(const std::string& name, Via& via);
/// The board a --via writes by default: openocd and dfu the STM32G474, gdb the emulated mps2-an386.
image::BoardId defaultBoard(Via via);
/// --target when none is given: gdb the stub's address, openocd the adapter's configuration, dfu the USB id.
std::string defaultTarget(Via via);
/// A board name of the build ("stm32g474", "mps2_an386", "ast1030") → its id; kUnknown for anything else.
image::BoardId boardByName(const std::string& name);
/// "glove5" | "sea_finger" | "pantograph" → DeviceType; kAny for anything else.
protocol::DeviceType deviceByName(const std::string& name);

/// An image file that passed every check.
struct CheckedImage {
  image::ImageInfo info;
  const image::BoardPart* part = nullptr;
  std::vector<uint8_t> bytes;
};

/// What the image must be to go onto this board.
struct Expectation {
  image::BoardId board = image::BoardId::kUnknown;
  protocol::DeviceType device = protocol::DeviceType::kAny;  ///< kAny: any (not offered by the CLI)
  bool check_build_id = false;
  uint32_t build_id = 0;
};

/// Every check before writing: a raw image (not an ELF or Intel HEX file), the image-info block at its offset
/// (magic, layout version), its size against the file and against the part's flash, its CRC-32, the board, the
/// device type, the load address against the part's flash origin, and a non-zero build id (equal to the expected
/// one when given). Returns "" and fills `out`, or a message naming what was wrong.
std::string checkImage(const std::vector<uint8_t>& bytes, const Expectation& expect, CheckedImage& out);

/// The bytes of the file at `path`; false and `error` naming the file and the reason.
bool readImageFile(const std::string& path, std::vector<uint8_t>& bytes, std::string& error);

/// CRC-32 of a raw image with its image-info CRC field read as zero (what the build stores; zlib's CRC-32).
uint32_t imageCrc(const std::vector<uint8_t>& bytes);

/// The commands (argv each) that write `image_path` (already checked: `info`) through `via` at `target`.
/// gdb: writes the image, reads `info.image_size` bytes back into `readback_path`, resets the board and detaches.
std::vector<std::vector<std::string>> writeCommands(Via via, const std::string& target, const std::string& image_path,
                                                    const image::ImageInfo& info, const std::string& readback_path);

/// One argv as a POSIX shell command line (arguments with shell-special characters in single quotes).
std::string shellLine(const std::vector<std::string>& argv);

/// What `phalanx flash` was asked to do.
struct Request {
  std::string image_path;
  Via via = Via::kGdb;
  std::string target;     ///< "" = defaultTarget(via)
  Expectation expect;
  std::string device;     ///< "serial:<path>": handshake after writing and compare the build id; "" = none
  double handshake_timeout_s = 10.0;
  bool dry_run = false;
};

/// Exit codes of `phalanx flash` besides 0 and cli::kExitBadArguments (2).
constexpr int kExitImageRefused = 3;  ///< the image failed a check: nothing was written
constexpr int kExitWriteFailed = 4;   ///< the tool failed or the read-back differs
constexpr int kExitVerifyFailed = 5;  ///< written, but the board's handshake did not show the image's build id

/// Checks the image, then (unless dry_run, which prints the commands) runs the commands, compares the read-back
/// (gdb; openocd verifies itself) and handshakes over `device`. Prints what it does to stdout, errors to stderr.
int run(const Request& request);

}  // namespace phalanx::host::flash
