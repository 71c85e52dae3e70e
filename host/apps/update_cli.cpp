#include "update_cli.h"

#include <cstdio>

#include "cli_args.h"
#include "phalanx/host/flash.h"

namespace phalanx::host {

UpdateCommand::UpdateCommand(CLI::App& parent) {
  req.link.device.clear();  // no default device: an update must name its board
  app = parent.add_subcommand("update", "update a board's firmware over its own link (serial, USB, CAN-FD); the "
                                        "board boots a valid image whatever happens (docs/firmware-update.md)");
  app->add_option("image", req.image_path, "the raw image of the cross build (phalanx-<board>-<app>.bin)")->required();
  app->add_option("--device", req.link.device,
                  "sim:glove5 | sim:sea_finger | sim:pantograph | serial:PATH[@baud] | can:IF[:node][@fd|@fd-compact] | "
                  "usb:VID:PID[:serial]")
      ->required();
  app->add_option("--board", board, "the board the image must be linked for")->check(CLI::IsMember({"stm32g474"}));
  app->add_option("--timeout", req.timeout_s, "seconds to wait for the handshake and for any answer while sending")
      ->check(cli::inRange(0.5, 60.0));
  app->add_option("--reconnects", req.reconnects, "lost links reopened (and the update resumed) before giving up")
      ->check(cli::inRange(0u, 100u));
  app->add_option("--window", req.window, "chunks in flight")->check(cli::inRange(1u, 64u));
  app->add_flag("--force", req.force, "update even when the board already runs the image's build");
  app->add_flag("--dry-run", req.dry_run, "check the image and handshake with the board; write nothing");
  app->add_flag("--no-confirm", req.no_confirm,
                "leave the new image on trial: the board's next reset goes back to the previous one unless it is "
                "confirmed (phalanx param set update_trial 1)");
  app->add_option("--firmware-sim", req.link.firmware_sim, "sim: devices: path of the firmware-sim executable");
  app->add_option("--sim-flash", sim_flash,
                  "sim: devices: the simulated board's code flash file (kept between runs); required for sim:");
  app->add_option("--sim-flash-provision", sim_provision,
                  "sim: devices: the image the simulated board holds when --sim-flash is new (its factory image)");
}

int UpdateCommand::run() {
  auto bad = [](const std::string& what) {
    std::fprintf(stderr, "phalanx update: error: %s\n", what.c_str());
    return cli::kExitBadArguments;
  };
  if (const std::string err = validate(req.link); !err.empty()) return bad(err);
  const bool sim = req.link.device.rfind("sim:", 0) == 0;
  if (sim && sim_flash.empty()) return bad("--sim-flash FILE is required for a sim: device (the board's code flash)");
  if (!sim && (!sim_flash.empty() || !sim_provision.empty())) {
    return bad("--sim-flash and --sim-flash-provision: for sim: devices only, not '" + req.link.device + "'");
  }
  if (!sim_provision.empty() && sim_flash.empty()) return bad("--sim-flash-provision needs --sim-flash");
  if (req.link.device.rfind("can:", 0) == 0 && req.link.device.find("@classic") != std::string::npos) {
    return bad("--device " + req.link.device + ": firmware update messages travel on CAN-FD only");
  }
  if (sim) {
    req.link.sim_args = {"--flash", sim_flash};
    if (!sim_provision.empty()) req.link.sim_args.insert(req.link.sim_args.end(), {"--flash-provision", sim_provision});
  }
  req.board = flash::boardByName(board);
  return update::run(req);
}

}  // namespace phalanx::host
