// `phalanx flash`'s checks before anything is written (issue 24 item 3; docs/firmware-mcu.md "Flashing"): every
// kind of wrong image is refused with a message naming what was wrong, and the commands each --via runs.
// The images here are made by the test (an image-info block written field by field at offset 0x200, the CRC by zlib
// over a copy with the CRC field zeroed); tools/mcu/flash-test.sh does the same with the cross build's images.
#include <gtest/gtest.h>
#include <zlib.h>

#include <cstring>

#include "phalanx/host/flash.h"

namespace {
using namespace phalanx;
using host::flash::CheckedImage;
using host::flash::Expectation;

void put32(std::vector<uint8_t>& b, size_t at, uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + i] = static_cast<uint8_t>(v >> (8 * i));
}

struct Fields {
  uint32_t magic = 0x49584850u;  // "PHXI"
  uint16_t layout = 1;
  uint8_t device = 1;             // glove5
  uint8_t board = 1;              // stm32g474
  uint32_t build_id = 0xbbf9253cu;
  uint32_t load = 0x08000000u;
};

/// A raw image of `size` bytes with a pseudo-random body and a filled-in image-info block.
std::vector<uint8_t> makeImage(size_t size, const Fields& f = {}) {
  std::vector<uint8_t> b(size);
  uint32_t x = 12345;
  for (auto& byte : b) byte = static_cast<uint8_t>((x = x * 1103515245u + 12345u) >> 24);
  const size_t o = 0x200;
  put32(b, o, f.magic);
  b[o + 4] = static_cast<uint8_t>(f.layout);
  b[o + 5] = 0;
  b[o + 6] = 32;
  b[o + 7] = 0;
  b[o + 8] = f.device;
  b[o + 9] = f.board;
  b[o + 10] = b[o + 11] = 0;
  put32(b, o + 12, f.build_id);
  put32(b, o + 16, f.load);
  put32(b, o + 20, static_cast<uint32_t>(size));
  put32(b, o + 24, 0);
  put32(b, o + 28, 0);
  const uLong crc = crc32(crc32(0L, Z_NULL, 0), b.data(), static_cast<uInt>(b.size()));
  put32(b, o + 24, static_cast<uint32_t>(crc));
  return b;
}

Expectation glove5OnStm32() {
  Expectation e;
  e.board = image::BoardId::kStm32g474;
  e.device = protocol::DeviceType::kGlove5;
  return e;
}

std::string check(const std::vector<uint8_t>& b, const Expectation& e = glove5OnStm32()) {
  CheckedImage out;
  return host::flash::checkImage(b, e, out);
}

}  // namespace

TEST(FlashImage, AWellFormedImageForThisBoardAndDevicePasses) {
  const auto b = makeImage(40000);
  CheckedImage out;
  ASSERT_EQ(host::flash::checkImage(b, glove5OnStm32(), out), "");
  EXPECT_EQ(out.info.build_id, 0xbbf9253cu);
  EXPECT_EQ(out.info.image_size, 40000u);
  EXPECT_STREQ(out.part->name, "stm32g474");
  EXPECT_EQ(out.bytes, b);
  EXPECT_EQ(host::flash::imageCrc(b), out.info.image_crc32) << "the CRC the build stores is the one recomputed";
}

TEST(FlashImage, AnImageForAnotherDeviceIsRefusedNamingBoth) {
  Fields f;
  f.device = 3;  // pantograph
  const std::string err = check(makeImage(40000, f));
  EXPECT_NE(err.find("wrong device"), std::string::npos) << err;
  EXPECT_NE(err.find("pantograph"), std::string::npos) << err;
  EXPECT_NE(err.find("glove5"), std::string::npos) << err;
}

TEST(FlashImage, AnImageForAnotherBoardIsRefusedNamingBoth) {
  Fields f;
  f.board = 2;  // mps2_an386
  f.load = 0;
  const std::string err = check(makeImage(40000, f));
  EXPECT_NE(err.find("wrong board"), std::string::npos) << err;
  EXPECT_NE(err.find("mps2_an386"), std::string::npos) << err;
  EXPECT_NE(err.find("stm32g474"), std::string::npos) << err;
}

TEST(FlashImage, ACorruptImageIsRefusedByItsCrcWhereverTheByteIs) {
  const auto good = makeImage(40000);
  for (const size_t at : {size_t{0}, size_t{0x1ff}, size_t{0x200 + 12}, size_t{0x200 + 27}, size_t{5000}, size_t{39999}}) {
    auto b = good;
    b[at] ^= 0x10;
    const std::string err = check(b);
    EXPECT_FALSE(err.empty()) << "byte " << at;
    // A flipped byte inside the block may hit the magic or the size first: refused either way, and named.
    if (at < 0x200 || at >= 0x200 + 20) {
      EXPECT_NE(err.find("CRC mismatch"), std::string::npos) << at << ": " << err;
    }
  }
}

TEST(FlashImage, AnImageLargerThanThePartsFlashIsRefused) {
  const std::string err = check(makeImage(512 * 1024 + 4));
  EXPECT_NE(err.find("too large"), std::string::npos) << err;
  EXPECT_NE(err.find("524288"), std::string::npos) << err;
  EXPECT_EQ(check(makeImage(512 * 1024)), "") << "exactly the part's flash fits";
}

TEST(FlashImage, ATruncatedOrPaddedFileIsRefusedBeforeItsCrcIsTrusted) {
  auto b = makeImage(40000);
  b.resize(39000);
  EXPECT_NE(check(b).find("size mismatch"), std::string::npos) << check(b);
  b = makeImage(40000);
  b.push_back(0xff);
  EXPECT_NE(check(b).find("size mismatch"), std::string::npos) << check(b);
}

TEST(FlashImage, FilesThatAreNotARawPhalanxImageAreRefused) {
  std::vector<uint8_t> elf = makeImage(40000);
  std::memcpy(elf.data(), "\x7f" "ELF", 4);
  EXPECT_NE(check(elf).find("ELF"), std::string::npos);
  std::vector<uint8_t> hex(40000, '0');
  hex[0] = ':';
  EXPECT_NE(check(hex).find("Intel HEX"), std::string::npos);
  EXPECT_NE(check(std::vector<uint8_t>(100, 0)).find("too short"), std::string::npos);
  Fields f;
  f.magic = 0x12345678u;
  EXPECT_NE(check(makeImage(40000, f)).find("no image-info block"), std::string::npos);
  f = Fields{};
  f.layout = 2;
  EXPECT_NE(check(makeImage(40000, f)).find("layout version 2"), std::string::npos);
  EXPECT_NE(check(std::vector<uint8_t>(40000, 0)).find("no image-info block"), std::string::npos) << "a blank image";
}

TEST(FlashImage, ALoadAddressOtherThanThePartsFlashIsRefused) {
  Fields f;
  f.load = 0x08004000u;
  const std::string err = check(makeImage(40000, f));
  EXPECT_NE(err.find("load address 0x08004000"), std::string::npos) << err;
}

TEST(FlashImage, BuildIdZeroIsRefusedAndAnExpectedBuildIdIsEnforced) {
  Fields f;
  f.build_id = 0;
  EXPECT_NE(check(makeImage(40000, f)).find("build id 00000000"), std::string::npos);
  Expectation e = glove5OnStm32();
  e.check_build_id = true;
  e.build_id = 0x12345678u;
  const std::string err = check(makeImage(40000), e);
  EXPECT_NE(err.find("wrong build"), std::string::npos) << err;
  EXPECT_NE(err.find("bbf9253c"), std::string::npos) << err;
  e.build_id = 0xbbf9253cu;
  EXPECT_EQ(check(makeImage(40000), e), "");
}

TEST(FlashCommands, OpenocdProgramsVerifiesAndResetsAtTheImagesLoadAddress) {
  image::ImageInfo info;
  info.load_address = 0x08000000u;
  info.image_size = 40000;
  const auto c = host::flash::writeCommands(host::flash::Via::kOpenocd, "interface/stlink.cfg", "img.bin", info, "rb");
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(host::flash::shellLine(c[0]),
            "openocd -f interface/stlink.cfg -f target/stm32g4x.cfg -c 'program img.bin 0x08000000 verify reset exit'");
}

TEST(FlashCommands, DfuWritesTheInternalFlashAndLeaves) {
  image::ImageInfo info;
  info.load_address = 0x08000000u;
  const auto c = host::flash::writeCommands(host::flash::Via::kDfu, "0483:df11", "img.bin", info, "rb");
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(host::flash::shellLine(c[0]), "dfu-util -d 0483:df11 -a 0 -s 0x08000000:leave -D img.bin");
}

TEST(FlashCommands, GdbRestoresReadsBackTheWholeImageResetsAndDetaches) {
  image::ImageInfo info;
  info.load_address = 0;
  info.image_size = 0xbb14;
  const auto c = host::flash::writeCommands(host::flash::Via::kGdb, "localhost:1234", "img.bin", info, "/tmp/rb.bin");
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(host::flash::shellLine(c[0]),
            "gdb-multiarch -nx -batch -ex 'set confirm off' -ex 'target remote localhost:1234' -ex 'restore img.bin "
            "binary 0x00000000' -ex 'dump binary memory /tmp/rb.bin 0x00000000 0x0000bb14' -ex 'monitor system_reset' "
            "-ex detach");
}

TEST(FlashCommands, ShellLineQuotesWhatAShellWouldSplitOrExpand) {
  EXPECT_EQ(host::flash::shellLine({"a", "b c", "it's", "$x", ""}), "a 'b c' 'it'\\''s' '$x' ''");
}

TEST(FlashNames, BoardsDevicesAndViasByName) {
  host::flash::Via v{};
  EXPECT_TRUE(host::flash::parseVia("dfu", v));
  EXPECT_EQ(v, host::flash::Via::kDfu);
  EXPECT_FALSE(host::flash::parseVia("jtag", v));
  EXPECT_EQ(host::flash::defaultBoard(host::flash::Via::kOpenocd), image::BoardId::kStm32g474);
  EXPECT_EQ(host::flash::defaultBoard(host::flash::Via::kGdb), image::BoardId::kMps2An386);
  EXPECT_EQ(host::flash::boardByName("ast1030"), image::BoardId::kAst1030);
  EXPECT_EQ(host::flash::boardByName("ast1030-evb"), image::BoardId::kUnknown);
  EXPECT_EQ(host::flash::deviceByName("sea_finger"), protocol::DeviceType::kSeaFinger);
  EXPECT_EQ(host::flash::deviceByName("glove"), protocol::DeviceType::kAny);
}
