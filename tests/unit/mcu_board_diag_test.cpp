// The MCU boards' diagnostics wrapper: parameters 0x0080–0x00FF answered by the board, the rest by the app,
// exercised through the real firmware core over an in-memory link.
#include <gtest/gtest.h>

#include "../../firmware/mcu/include/phalanx/fw_mcu/board_diag.h"
#include "phalanx/fw/core.h"
#include "phalanx/protocol/codec.h"
#include "phalanx/protocol/devices.h"
#include "phalanx/sim/board.h"

namespace {

using namespace phalanx;

class TinyApp : public fw::DeviceApp {
 public:
  const protocol::DeviceLayout& layout() const override { return protocol::kSeaFingerLayout; }
  void init(hal::Board&) override {}
  uint16_t sense(float) override { return 0; }
  uint16_t control(const protocol::Command&, float) override { return 0; }
  void safe() override {}
  void fillSamples(int16_t*) const override {}
  protocol::ParamStatus getParam(uint16_t id, float& v) const override {
    if (id != 0x0100) return protocol::ParamStatus::kUnknownParam;
    v = 7.0f;
    return protocol::ParamStatus::kOk;
  }
  fw::SettingsHistory settingsHistory() const override { return {kLayouts, 1}; }
  static constexpr uint16_t kIds[] = {0x0100};
  static constexpr fw::SettingsLayout kLayouts[] = {{1, kIds, 1, nullptr, 0}};
};

class FakeDiag : public fw_mcu::DiagSource {
 public:
  bool diagGet(uint16_t id, float& v) const override {
    if (id == fw_mcu::diag_param::kTickWorst) { v = worst; return true; }
    if (id == fw_mcu::diag_param::kResetStats) { v = 0.0f; return true; }
    return false;
  }
  bool diagSet(uint16_t id, float) override {
    if (id != fw_mcu::diag_param::kResetStats) return false;
    worst = 0.0f;
    return true;
  }
  float worst = 12345.0f;
};

struct Rig {
  Rig() : board(2, 5, 2, pipe.end(0)), wrapped(app, diag), core(board.board(), wrapped, fw::CoreConfig{}) {}
  protocol::ParamValue ask(const protocol::ParamGet& get) {
    uint8_t buf[protocol::kMaxEncodedFrame];
    pipe.end(1).write(buf, protocol::encodeFrame(get, buf));
    return roundTrip();
  }
  protocol::ParamValue set(const protocol::ParamSet& s) {
    uint8_t buf[protocol::kMaxEncodedFrame];
    pipe.end(1).write(buf, protocol::encodeFrame(s, buf));
    return roundTrip();
  }
  protocol::ParamValue roundTrip() {
    board.clock().advanceUs(1000);
    core.tick();
    uint8_t b = 0;
    protocol::StreamDecoder dec;
    while (pipe.end(1).read(&b, 1) == 1) {
      if (dec.push(b) && dec.frame().id == static_cast<uint8_t>(protocol::MsgId::kParamValue)) {
        protocol::ParamValue v;
        if (protocol::decodePayload(dec.frame().payload, dec.frame().len, v)) return v;
      }
    }
    ADD_FAILURE() << "no ParamValue answer";
    return {};
  }
  sim::BytePipe pipe;
  sim::SimBoard board;
  TinyApp app;
  FakeDiag diag;
  fw_mcu::DiagApp wrapped;
  fw::FirmwareCore core;
};

}  // namespace

TEST(McuBoardDiag, BoardParametersAreAnsweredByTheBoard) {
  Rig rig;
  protocol::ParamGet get;
  get.param_id = fw_mcu::diag_param::kTickWorst;
  const auto v = rig.ask(get);
  EXPECT_EQ(v.status, protocol::ParamStatus::kOk);
  EXPECT_EQ(v.value, 12345.0f);
}

TEST(McuBoardDiag, DeviceParametersStillReachTheApp) {
  Rig rig;
  protocol::ParamGet get;
  get.param_id = 0x0100;
  const auto v = rig.ask(get);
  EXPECT_EQ(v.status, protocol::ParamStatus::kOk);
  EXPECT_EQ(v.value, 7.0f);
}

TEST(McuBoardDiag, UnknownBoardParameterIsUnknownAndReadOnlyOnesRefuseWrites) {
  Rig rig;
  protocol::ParamGet get;
  get.param_id = 0x00F0;
  EXPECT_EQ(rig.ask(get).status, protocol::ParamStatus::kUnknownParam);
  protocol::ParamSet set;
  set.param_id = fw_mcu::diag_param::kTickWorst;
  set.value = 1.0f;
  EXPECT_EQ(rig.set(set).status, protocol::ParamStatus::kReadOnly);
  set.param_id = fw_mcu::diag_param::kResetStats;
  EXPECT_EQ(rig.set(set).status, protocol::ParamStatus::kOk);
  EXPECT_EQ(rig.diag.worst, 0.0f);
}

TEST(McuBoardDiag, TheWrapperPassesOnTheAppsSettingsLayoutSoTheBoardsStoreKeepsItsSettings) {
  Rig rig;
  const fw::SettingsHistory h = rig.wrapped.settingsHistory();
  ASSERT_EQ(h.count, 1);
  EXPECT_EQ(h.layouts, TinyApp::kLayouts);
}
