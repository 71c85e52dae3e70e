#include "phalanx/host/flash.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>

#include "phalanx/host/mcu_diag.h"
#include "phalanx/host/session.h"
#include "phalanx/linux/fd_link.h"
#include "phalanx/protocol/devices.h"

extern char** environ;

namespace phalanx::host::flash {

namespace {

constexpr size_t kCrcOffset = image::kImageInfoOffset + offsetof(image::ImageInfo, image_crc32);

std::string hex32(uint32_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "%08x", static_cast<unsigned>(v));
  return b;
}

std::string boardName(uint8_t id) {
  const image::BoardPart* p = image::boardPart(static_cast<image::BoardId>(id));
  return p ? p->name : "unknown board " + std::to_string(id);
}

std::string deviceName(uint8_t type) {
  const protocol::DeviceLayout* l = protocol::layoutFor(static_cast<protocol::DeviceType>(type));
  return l ? l->name : "unknown device type " + std::to_string(type);
}

uint32_t le32(const std::vector<uint8_t>& b, size_t at) {
  return static_cast<uint32_t>(b[at]) | static_cast<uint32_t>(b[at + 1]) << 8 | static_cast<uint32_t>(b[at + 2]) << 16 |
         static_cast<uint32_t>(b[at + 3]) << 24;
}
uint16_t le16(const std::vector<uint8_t>& b, size_t at) {
  return static_cast<uint16_t>(b[at] | b[at + 1] << 8);
}

/// The block's fields, read byte by byte (the file's layout is little-endian whatever the host is).
image::ImageInfo readInfo(const std::vector<uint8_t>& b) {
  const size_t o = image::kImageInfoOffset;
  image::ImageInfo i;
  i.magic = le32(b, o + 0);
  i.layout_version = le16(b, o + 4);
  i.info_size = le16(b, o + 6);
  i.device_type = b[o + 8];
  i.board = b[o + 9];
  i.build_id = le32(b, o + 12);
  i.load_address = le32(b, o + 16);
  i.image_size = le32(b, o + 20);
  i.image_crc32 = le32(b, o + 24);
  return i;
}

std::string hexAddr(uint32_t v) { return "0x" + hex32(v); }

/// Runs argv (no shell), its output going to ours; returns its exit status, or -1 with `error` when it did not run.
int runTool(const std::vector<std::string>& argv, std::string& error) {
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  // stdout of the tool goes to our stderr: stdout stays this command's own report.
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, STDERR_FILENO, STDOUT_FILENO);
  const int rc = posix_spawnp(&pid, args[0], &fa, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) {
    error = "cannot run " + argv[0] + ": " + std::strerror(rc) + " (docs/firmware-mcu.md \"Flashing\" lists the packages)";
    return -1;
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) {
      error = "waitpid: " + std::string(std::strerror(errno));
      return -1;
    }
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  error = argv[0] + " was killed by signal " + std::to_string(WTERMSIG(status));
  return -1;
}

/// After writing: handshake over the board's link; its build id and device type must be the image's.
int verifyByHandshake(const Request& r, const image::ImageInfo& info) {
  // serial:PATH[@baud], as `phalanx run --device` (no baud: the port's setting is kept).
  std::string path = r.device.substr(7);
  unsigned baud = 0;
  if (const auto at = path.find('@'); at != std::string::npos) {
    baud = static_cast<unsigned>(std::strtoul(path.c_str() + at + 1, nullptr, 10));
    path = path.substr(0, at);
  }
  linux_hal::SerialLink link;
  if (const std::string err = link.open(path, baud); !err.empty()) {
    std::fprintf(stderr, "phalanx flash: error: written, but the board's link: %s\n", err.c_str());
    return kExitVerifyFailed;
  }
  HostSession session(link);
  const auto device = static_cast<protocol::DeviceType>(info.device_type);
  if (const std::string err = handshakeBoard(link, session, r.handshake_timeout_s, device, path); !err.empty()) {
    std::fprintf(stderr, "phalanx flash: error: written, but the board did not handshake as a %s: %s\n",
                 deviceName(info.device_type).c_str(), err.c_str());
    return kExitVerifyFailed;
  }
  const uint32_t got = session.deviceInfo().firmware_build_id;
  if (got != info.build_id) {
    std::fprintf(stderr,
                 "phalanx flash: error: build id mismatch: the board runs build %s, the image is build %s (the write "
                 "did not take, or another board answered on %s)\n",
                 hex32(got).c_str(), hex32(info.build_id).c_str(), path.c_str());
    return kExitVerifyFailed;
  }
  std::printf("handshake: %s on %s answered as %s, build %s: matches the image\n", deviceName(info.device_type).c_str(),
              path.c_str(), session.layout()->name, hex32(got).c_str());
  return 0;
}

}  // namespace

bool readImageFile(const std::string& path, std::vector<uint8_t>& bytes, std::string& error) {
  std::ifstream f(path, std::ios::binary);
  if (!f) {
    error = "cannot read image '" + path + "': " + std::strerror(errno);
    return false;
  }
  bytes.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  return true;
}

bool parseVia(const std::string& name, Via& via) {
  if (name == "gdb") via = Via::kGdb;
  else if (name == "openocd") via = Via::kOpenocd;
  else if (name == "dfu") via = Via::kDfu;
  else return false;
  return true;
}

image::BoardId defaultBoard(Via via) { return via == Via::kGdb ? image::BoardId::kMps2An386 : image::BoardId::kStm32g474; }

std::string defaultTarget(Via via) {
  switch (via) {
    case Via::kGdb: return "localhost:1234";           // qemu-system-arm -gdb tcp::1234 (= -s)
    case Via::kOpenocd: return "interface/stlink.cfg";  // ST-Link (V2, V2-1, V3) over SWD
    case Via::kDfu: return "0483:df11";                 // the STM32 ROM bootloader's USB VID:PID (AN2606)
  }
  return "";
}

image::BoardId boardByName(const std::string& name) {
  for (const image::BoardPart& p : image::kBoardParts) {
    if (name == p.name) return p.id;
  }
  return image::BoardId::kUnknown;
}

protocol::DeviceType deviceByName(const std::string& name) {
  for (const auto t : {protocol::DeviceType::kGlove5, protocol::DeviceType::kSeaFinger, protocol::DeviceType::kPantograph}) {
    if (name == protocol::layoutFor(t)->name) return t;
  }
  return protocol::DeviceType::kAny;
}

uint32_t imageCrc(const std::vector<uint8_t>& bytes) {
  static const uint8_t kZero[4] = {0, 0, 0, 0};
  uLong crc = crc32(0L, Z_NULL, 0);
  if (bytes.size() < kCrcOffset + 4) return static_cast<uint32_t>(crc32(crc, bytes.data(), static_cast<uInt>(bytes.size())));
  crc = crc32(crc, bytes.data(), static_cast<uInt>(kCrcOffset));
  crc = crc32(crc, kZero, 4);
  crc = crc32(crc, bytes.data() + kCrcOffset + 4, static_cast<uInt>(bytes.size() - kCrcOffset - 4));
  return static_cast<uint32_t>(crc);
}

std::string checkImage(const std::vector<uint8_t>& bytes, const Expectation& expect, CheckedImage& out) {
  if (bytes.size() >= 4 && bytes[0] == 0x7f && bytes[1] == 'E' && bytes[2] == 'L' && bytes[3] == 'F') {
    return "the image is an ELF file: give the raw image (the .bin built next to it)";
  }
  if (!bytes.empty() && bytes[0] == ':') return "the image looks like Intel HEX: give the raw image (the .bin built next to it)";
  if (bytes.size() < image::kImageInfoOffset + sizeof(image::ImageInfo)) {
    return "the image has " + std::to_string(bytes.size()) + " bytes: too short to hold an image-info block at offset " +
           hexAddr(image::kImageInfoOffset);
  }
  const image::ImageInfo info = readInfo(bytes);
  if (info.magic != image::kImageInfoMagic) {
    return "no image-info block at offset " + hexAddr(image::kImageInfoOffset) + " (magic " + hex32(info.magic) +
           ", expected " + hex32(image::kImageInfoMagic) + "): not a Phalanx firmware image";
  }
  if (info.layout_version != image::kImageInfoLayoutVersion || info.info_size != sizeof(image::ImageInfo)) {
    return "image-info layout version " + std::to_string(info.layout_version) + " (" + std::to_string(info.info_size) +
           " bytes): this phalanx reads layout " + std::to_string(image::kImageInfoLayoutVersion) + " only";
  }
  if (info.image_size != bytes.size()) {
    return "size mismatch: the image-info block says " + std::to_string(info.image_size) + " bytes, the file has " +
           std::to_string(bytes.size()) + " (truncated or padded image)";
  }
  const image::BoardPart* part = image::boardPart(static_cast<image::BoardId>(info.board));
  if (part != nullptr && info.image_size > part->flash_size) {
    return "image too large: " + std::to_string(info.image_size) + " bytes, the " + part->name + " has " +
           std::to_string(part->flash_size) + " bytes of flash";
  }
  if (const uint32_t crc = imageCrc(bytes); crc != info.image_crc32) {
    return "CRC mismatch: the image-info block says " + hex32(info.image_crc32) + ", the image's CRC-32 is " + hex32(crc) +
           " (corrupt image)";
  }
  if (part == nullptr || part->id != expect.board) {
    const image::BoardPart* want = image::boardPart(expect.board);
    return "wrong board: the image is for the " + boardName(info.board) + ", this board is the " +
           (want ? want->name : std::string("(no board)"));
  }
  if (expect.device != protocol::DeviceType::kAny && info.device_type != static_cast<uint8_t>(expect.device)) {
    return "wrong device: the image is a " + deviceName(info.device_type) + " image, the board drives a " +
           deviceName(static_cast<uint8_t>(expect.device));
  }
  if (info.load_address != part->flash_origin) {
    return "load address " + hexAddr(info.load_address) + " is not the " + part->name + "'s flash origin " +
           hexAddr(part->flash_origin);
  }
  if (info.build_id == 0) {
    return "the image has build id 00000000 (built outside a git checkout): the board's answer after flashing could "
           "not be told from another build";
  }
  if (expect.check_build_id && info.build_id != expect.build_id) {
    return "wrong build: the image is build " + hex32(info.build_id) + ", --build-id asks for " + hex32(expect.build_id);
  }
  out.info = info;
  out.part = part;
  out.bytes = bytes;
  return "";
}

std::vector<std::vector<std::string>> writeCommands(Via via, const std::string& target, const std::string& image_path,
                                                    const image::ImageInfo& info, const std::string& readback_path) {
  const std::string addr = hexAddr(info.load_address);
  switch (via) {
    case Via::kGdb:
      // QEMU's gdbstub halts the emulated core while gdb is attached; `restore ... binary BIAS` writes the file's
      // bytes at BIAS, `dump binary memory` reads them back, `monitor system_reset` resets the board (the core
      // reads its vector table from the new image) and `detach` lets it run.
      return {{"gdb-multiarch", "-nx", "-batch", "-ex", "set confirm off", "-ex", "target remote " + target, "-ex",
               "restore " + image_path + " binary " + addr, "-ex",
               "dump binary memory " + readback_path + " " + addr + " " + hexAddr(info.load_address + info.image_size),
               "-ex", "monitor system_reset", "-ex", "detach"}};
    case Via::kOpenocd:
      // `program` erases the sectors the image covers, writes, reads back and compares (verify), then resets.
      return {{"openocd", "-f", target, "-f", "target/stm32g4x.cfg", "-c",
               "program " + image_path + " " + addr + " verify reset exit"}};
    case Via::kDfu:
      // DfuSe: alternate setting 0 is the internal flash; ":leave" starts the new image after the download.
      return {{"dfu-util", "-d", target, "-a", "0", "-s", addr + ":leave", "-D", image_path}};
  }
  return {};
}

std::string shellLine(const std::vector<std::string>& argv) {
  std::string line;
  for (const std::string& a : argv) {
    if (!line.empty()) line += ' ';
    const bool plain = !a.empty() && a.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                                         "0123456789-_./:=@%+,") == std::string::npos;
    if (plain) {
      line += a;
      continue;
    }
    line += '\'';
    for (const char c : a) line += c == '\'' ? std::string("'\\''") : std::string(1, c);
    line += '\'';
  }
  return line;
}

int run(const Request& r) {
  std::vector<uint8_t> bytes;
  std::string error;
  if (!readImageFile(r.image_path, bytes, error)) {
    std::fprintf(stderr, "phalanx flash: error: %s\n", error.c_str());
    return kExitImageRefused;
  }
  CheckedImage img;
  if (const std::string err = checkImage(bytes, r.expect, img); !err.empty()) {
    std::fprintf(stderr, "phalanx flash: error: %s: %s; nothing was written\n", r.image_path.c_str(), err.c_str());
    return kExitImageRefused;
  }
  if (r.image_path.find_first_of(" \t\n\"'\\") != std::string::npos) {
    // gdb's restore/dump and OpenOCD's program take the file name inside one command string.
    std::fprintf(stderr, "phalanx flash: error: %s: the image path must not contain spaces or quotes; nothing was "
                 "written\n", r.image_path.c_str());
    return kExitImageRefused;
  }
  std::printf("image %s: %s for the %s, build %s, %u bytes at %s, crc32 %s: ok\n", r.image_path.c_str(),
              deviceName(img.info.device_type).c_str(), img.part->name, hex32(img.info.build_id).c_str(),
              static_cast<unsigned>(img.info.image_size), hexAddr(img.info.load_address).c_str(),
              hex32(img.info.image_crc32).c_str());

  const std::string target = r.target.empty() ? defaultTarget(r.via) : r.target;
  const char* tmp = std::getenv("TMPDIR");
  const std::string readback = std::string(tmp && *tmp ? tmp : "/tmp") + "/phalanx-flash-readback-" +
                               std::to_string(getpid()) + ".bin";
  const auto commands = writeCommands(r.via, target, r.image_path, img.info, readback);
  if (r.dry_run) {
    for (const auto& argv : commands) std::printf("%s\n", shellLine(argv).c_str());
    return 0;
  }
  for (const auto& argv : commands) {
    std::printf("running: %s\n", shellLine(argv).c_str());
    std::fflush(stdout);
    const int rc = runTool(argv, error);
    if (rc != 0) {
      std::fprintf(stderr, "phalanx flash: error: %s\n",
                   rc < 0 ? error.c_str() : (argv[0] + " failed (exit status " + std::to_string(rc) + ")").c_str());
      return kExitWriteFailed;
    }
  }
  if (r.via == Via::kGdb) {
    std::vector<uint8_t> back;
    const bool read = readImageFile(readback, back, error);
    unlink(readback.c_str());
    if (!read || back != img.bytes) {
      std::fprintf(stderr, "phalanx flash: error: read-back differs from the image (%s)\n",
                   read ? (std::to_string(back.size()) + " bytes read back").c_str() : error.c_str());
      return kExitWriteFailed;
    }
    std::printf("read back: %u bytes equal to the image\n", static_cast<unsigned>(back.size()));
  } else if (r.via == Via::kOpenocd) {
    std::printf("read back: verified by openocd (program ... verify)\n");
  }
  if (r.device.empty()) {
    std::printf("handshake: not done (no --device): the board's build id was not checked\n");
    return 0;
  }
  return verifyByHandshake(r, img.info);
}

}  // namespace phalanx::host::flash
