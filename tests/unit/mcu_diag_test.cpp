// `phalanx mcu-diag`'s output (issue 26 item 9): counts as integers though the protocol carries every parameter
// as an f32, the tick unit as the real number it is, and the firmware's build id from the handshake.
#include <gtest/gtest.h>

#include "phalanx/host/mcu_diag.h"

TEST(McuDiag, CountsAreIntegersTheUnitIsARealAndTheBuildIdIsShown) {
  phalanx::protocol::HelloAck ack;
  ack.firmware_build_id = 0x1a2b3c4du;
  ack.tick_rate_hz = 1000;
  // IDs of firmware/mcu/include/phalanx/fw_mcu/board_diag.h (docs/firmware-mcu.md: 0x0080-0x0089).
  const std::map<uint16_t, float> values{{0x0080, 123456.0f}, {0x0081, 7701.0f}, {0x0085, 5.88f}, {0x0086, 6.0f}};
  const nlohmann::json j = phalanx::host::mcuDiagJson("sea_finger", ack, values);
  EXPECT_EQ(j["device_type"], "sea_finger");
  EXPECT_EQ(j["firmware"]["build_id"], "1a2b3c4d");
  EXPECT_EQ(j["firmware"]["tick_rate_hz"], 1000);
  EXPECT_EQ(j["firmware"]["protocol_version"], phalanx::protocol::kProtocolVersion);
  const nlohmann::json& p = j["params"];
  EXPECT_TRUE(p["overruns"].is_number_unsigned());
  EXPECT_EQ(p["overruns"].dump(), "6") << "not 6.0";
  EXPECT_EQ(p["tick_count"].get<uint64_t>(), 123456u);
  EXPECT_EQ(p["tick_worst"].dump(), "7701");
  EXPECT_TRUE(p["tick_unit_ns"].is_number_float());
  EXPECT_NEAR(p["tick_unit_ns"].get<double>(), 5.88, 1e-6);
  EXPECT_FALSE(p.contains("plant_ms")) << "a parameter not read is not invented";
}
