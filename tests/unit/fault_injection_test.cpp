// firmware-sim --inject (firmware/sim/fault_injection.cpp): the schedule's parser and what each fault does to the
// board's inputs. The firmware's detection of them runs end to end in the soak (docs/soak.md).
#include "phalanx/fw_sim/fault_injection.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

namespace phalanx::fw_sim {
namespace {

TEST(FaultInjectionParse, AcceptsEachKind) {
  Injection j;
  ASSERT_EQ(parseInjection("sensor-range@2.5", j), "");
  EXPECT_EQ(j.kind, Injection::Kind::kSensorRange);
  EXPECT_EQ(j.start_us, 2500000u);
  EXPECT_EQ(j.end_us, UINT64_MAX);
  ASSERT_EQ(parseInjection("sensor-stuck@0", j), "");
  EXPECT_EQ(j.kind, Injection::Kind::kSensorStuck);
  ASSERT_EQ(parseInjection("estop@1+0.25", j), "");
  EXPECT_EQ(j.kind, Injection::Kind::kEstop);
  EXPECT_EQ(j.start_us, 1000000u);
  EXPECT_EQ(j.end_us, 1250000u);
}

TEST(FaultInjectionParse, RefusesBadArgumentsNamingThem) {
  Injection j;
  EXPECT_EQ(parseInjection("estop", j), "--inject 'estop': expected KIND@T[+D] (e.g. sensor-range@2.5, estop@1+0.5)");
  EXPECT_EQ(parseInjection("melt@1", j), "--inject 'melt@1': unknown kind 'melt' (sensor-range, sensor-stuck, estop)");
  EXPECT_EQ(parseInjection("sensor-range@-1", j), "--inject 'sensor-range@-1': the time '-1' is not seconds in [0, 86400]");
  EXPECT_EQ(parseInjection("sensor-range@nan", j), "--inject 'sensor-range@nan': the time 'nan' is not seconds in [0, 86400]");
  EXPECT_EQ(parseInjection("sensor-range@2s", j), "--inject 'sensor-range@2s': the time '2s' is not seconds in [0, 86400]");
  EXPECT_EQ(parseInjection("estop@1", j), "--inject 'estop@1': an e-stop press needs its length: estop@T+D, D > 0 seconds");
  EXPECT_EQ(parseInjection("estop@1+0", j), "--inject 'estop@1+0': an e-stop press needs its length: estop@T+D, D > 0 seconds");
  EXPECT_EQ(parseInjection("sensor-stuck@1+2", j), "--inject 'sensor-stuck@1+2': a sensor fault lasts to the end: no +D");
}

Injection at(const char* text) {
  Injection j;
  EXPECT_EQ(parseInjection(text, j), "");
  return j;
}

TEST(FaultInjector, StuckHoldsTheValueOfItsStartWhateverThePlantWrites) {
  std::FILE* log = std::tmpfile();
  FaultInjector inj({at("sensor-stuck@0.002")}, {false, 3, 0, 0});
  sim::SimIo io;
  io.adc[3] = 1000;
  inj.apply(1000, io, log);
  EXPECT_EQ(io.adc[3], 1000);
  io.adc[3] = 1100;  // the plant's new reading at the start tick: frozen from here on
  inj.apply(2000, io, log);
  for (int32_t v : {1200, 900, 3000}) {
    io.adc[3] = v;
    inj.apply(3000, io, log);
    EXPECT_EQ(io.adc[3], 1100);
  }
  std::fclose(log);
}

TEST(FaultInjector, RangeReadsAnOpenSensorOrAJumpingEncoder) {
  std::FILE* log = std::tmpfile();
  FaultInjector adc({at("sensor-range@0")}, {false, 0, 0, 0});
  sim::SimIo io;
  io.adc[0] = 2048;
  adc.apply(0, io, log);
  EXPECT_EQ(io.adc[0], 0);
  FaultInjector enc({at("sensor-range@0")}, {true, 1, 0, 2000});
  io.encoder[1] = 50;
  enc.apply(0, io, log);
  EXPECT_EQ(io.encoder[1], 2050);
  io.encoder[1] = 51;  // the plant writes the true reading again; every tick jumps again
  enc.apply(1000, io, log);
  EXPECT_EQ(io.encoder[1], 4050);
  std::fclose(log);
}

TEST(FaultInjector, EstopIsPressedForItsLengthThenReleasedAndLogged) {
  std::FILE* log = std::tmpfile();
  FaultInjector inj({at("estop@0.001+0.002")}, {false, 0, 0, 0});
  sim::SimIo io;
  inj.apply(0, io, log);
  EXPECT_FALSE(io.estop_pressed);
  inj.apply(1000, io, log);
  EXPECT_TRUE(io.estop_pressed);
  inj.apply(2000, io, log);
  EXPECT_TRUE(io.estop_pressed);
  inj.apply(3000, io, log);
  EXPECT_FALSE(io.estop_pressed);
  std::rewind(log);
  char text[256] = {};
  const size_t n = std::fread(text, 1, sizeof text - 1, log);
  EXPECT_EQ(std::string(text, n),
            "firmware-sim: INJECT estop started t_us=1000\nfirmware-sim: INJECT estop ended t_us=3000\n");
  std::fclose(log);
}

}  // namespace
}  // namespace phalanx::fw_sim
