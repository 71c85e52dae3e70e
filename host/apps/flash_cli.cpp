#include "flash_cli.h"

#include <cstdio>
#include <cstdlib>

#include "cli_args.h"
#include "phalanx/host/flash.h"

namespace phalanx::host {

FlashCommand::FlashCommand(CLI::App& parent) {
  app = parent.add_subcommand("flash",
                              "check a firmware image (device, board, build id, size, CRC) and write it into a board "
                              "(docs/firmware-mcu.md \"Flashing\")");
  app->add_option("image", image, "the raw image of the cross build: build/mcu-<board>/phalanx-<board>-<app>.bin")
      ->required();
  app->add_option("--via", via, "gdb (a gdb stub: QEMU's, for the emulated boards), openocd (ST-Link/SWD) or dfu "
                                "(the STM32 ROM DFU bootloader over USB)")
      ->check(CLI::IsMember({"gdb", "openocd", "dfu"}));
  app->add_option("--target", target,
                  "gdb: the stub's HOST:PORT [localhost:1234]; openocd: the adapter's interface configuration "
                  "[interface/stlink.cfg]; dfu: the bootloader's USB VID:PID [0483:df11]");
  app->add_option("--board", board, "the board written: stm32g474, mps2_an386 or ast1030 [openocd, dfu: stm32g474; "
                                    "gdb: mps2_an386]")
      ->check(CLI::IsMember({"stm32g474", "mps2_an386", "ast1030"}));
  app->add_option("--device-type", device_type, "the device this board drives: the image must be its app")
      ->check(CLI::IsMember({"glove5", "sea_finger", "pantograph"}))
      ->required();
  app->add_option("--build-id", build_id, "refuse an image whose build id is not this (8 hex digits)");
  app->add_option("--device", device, "serial:<path>[@baud] of the board's link: after writing, handshake and compare "
                                      "the build id with the image's");
  app->add_option("--timeout", timeout_s, "seconds to wait for the board's handshake after writing")
      ->check(cli::inRange(0.5, 120.0));
  app->add_flag("--dry-run", dry_run, "check the image and print the command(s) that would write it; run nothing");
}

int FlashCommand::run() const {
  flash::Request r;
  r.image_path = image;
  flash::parseVia(via, r.via);
  r.target = target;
  r.expect.board = board.empty() ? flash::defaultBoard(r.via) : flash::boardByName(board);
  r.expect.device = flash::deviceByName(device_type);
  if (!build_id.empty()) {
    char* end = nullptr;
    const unsigned long v = std::strtoul(build_id.c_str(), &end, 16);
    if (build_id.size() > 8 || *end != '\0') {
      std::fprintf(stderr, "phalanx: error: --build-id: expected up to 8 hex digits, got '%s'\n", build_id.c_str());
      return cli::kExitBadArguments;
    }
    r.expect.check_build_id = true;
    r.expect.build_id = static_cast<uint32_t>(v);
  }
  if (!device.empty()) {
    const auto at = device.find('@');
    char* end = nullptr;
    const unsigned long baud = at == std::string::npos ? 1 : std::strtoul(device.c_str() + at + 1, &end, 10);
    if (device.rfind("serial:", 0) != 0 || device.size() <= 7 ||
        (at != std::string::npos && (at + 1 == device.size() || *end != '\0' || baud == 0 || baud > 4000000))) {
      std::fprintf(stderr, "phalanx: error: --device: expected serial:<path>[@baud], got '%s'\n", device.c_str());
      return cli::kExitBadArguments;
    }
  }
  r.device = device;
  r.handshake_timeout_s = timeout_s;
  r.dry_run = dry_run;
  return flash::run(r);
}

}  // namespace phalanx::host
