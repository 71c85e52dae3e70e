// The daemon's e-stop / drive-enable logic (host/src/safety_io.cpp) over mock lines: presses stop at once and drop
// the enable line, a lost line counts as pressed, resets are refused until the e-stop stayed released for the
// debounce time, a failed enable write stops. The kernel side (libgpiod on gpio-sim) is tests/vm/gpio_test.sh.
#include <gtest/gtest.h>

#include <deque>

#include "phalanx/host/config.h"
#include "phalanx/host/daemon.h"
#include "phalanx/host/safety_io.h"
#include "phalanx/linux/gpio.h"

using phalanx::host::SafetyIo;
using phalanx::host::SafetyIoConfig;
using phalanx::host::StopCause;
using phalanx::linux_hal::EstopSample;

namespace {

constexpr uint64_t kMs = 1000000ull;

class MockEstop : public phalanx::linux_hal::EstopSource {
 public:
  // Level now, with optional edges queued for the next poll.
  bool active = false;
  bool lost = false;
  bool reopen_ok = false;
  int reopens = 0;
  std::deque<std::pair<bool, uint64_t>> edges;  // (to_active, kernel ns)
  EstopSample poll() override {
    EstopSample s;
    if (lost) {
      s.error = 19;
      return s;
    }
    for (const auto& [to_active, t] : edges) {
      if (to_active && !s.press_seen) {
        s.press_seen = true;
        s.press_edge_ns = t;
      } else if (!to_active) {
        s.release_edge_ns = t;
      }
    }
    edges.clear();
    s.ok = true;
    s.active = active;
    return s;
  }
  bool reopen() override {
    ++reopens;
    if (reopen_ok) lost = false;
    return reopen_ok;
  }
};

class MockOutput : public phalanx::linux_hal::DigitalOutput {
 public:
  bool level = false;
  bool fail = false;
  int writes = 0;
  bool write(bool a) override {
    ++writes;
    if (fail) return false;
    level = a;
    return true;
  }
};

SafetyIoConfig cfg() {
  SafetyIoConfig c;
  c.release_debounce_ns = 20 * kMs;
  c.enable_refresh_ns = 10 * kMs;
  c.reopen_interval_ns = 1000 * kMs;
  return c;
}

}  // namespace

TEST(SafetyIo, StartsRunningWithTheEnableLineHighWhenReleased) {
  MockEstop e;
  MockOutput en;
  SafetyIo s(&e, &en, cfg());
  s.start(true, 1 * kMs);
  EXPECT_FALSE(s.stopped());
  EXPECT_TRUE(en.level);
  EXPECT_FALSE(s.update(2 * kMs));
  EXPECT_TRUE(en.level);
}

TEST(SafetyIo, APressStopsInTheSamePollAndDropsTheEnableLine) {
  MockEstop e;
  MockOutput en;
  SafetyIo s(&e, &en, cfg());
  s.start(true, 0);
  e.active = true;
  e.edges.push_back({true, 5 * kMs});
  EXPECT_TRUE(s.update(6 * kMs));
  EXPECT_TRUE(s.stopped());
  EXPECT_EQ(s.cause(), StopCause::kEstopPressed);
  EXPECT_EQ(s.stopEdgeNs(), 5 * kMs);
  EXPECT_FALSE(en.level);
  EXPECT_FALSE(s.update(7 * kMs)) << "a stop is reported once";
}

TEST(SafetyIo, APressShorterThanOnePollStillStops) {
  MockEstop e;
  MockOutput en;
  SafetyIo s(&e, &en, cfg());
  s.start(true, 0);
  e.edges.push_back({true, 5 * kMs});
  e.edges.push_back({false, 5 * kMs + 1000});  // bounced back before the daemon read the level
  EXPECT_TRUE(s.update(6 * kMs));
  EXPECT_TRUE(s.stopped());
  EXPECT_FALSE(en.level);
}

TEST(SafetyIo, StaysStoppedAfterReleaseUntilAnExplicitReset) {
  MockEstop e;
  MockOutput en;
  SafetyIo s(&e, &en, cfg());
  s.start(true, 0);
  e.active = true;
  e.edges.push_back({true, 1 * kMs});
  s.update(1 * kMs);
  e.active = false;
  e.edges.push_back({false, 100 * kMs});
  for (uint64_t t = 101; t < 2000; t += 50) {
    s.update(t * kMs);
    EXPECT_TRUE(s.stopped());
    EXPECT_FALSE(en.level);
  }
  EXPECT_EQ(s.requestReset(2000 * kMs), nullptr);
  s.update(2000 * kMs);
  EXPECT_FALSE(s.stopped());
  EXPECT_TRUE(en.level);
  EXPECT_EQ(s.counters().resets, 1u);
}

TEST(SafetyIo, RefusesAResetWhilePressedAndBeforeTheReleaseDebounce) {
  MockEstop e;
  MockOutput en;
  SafetyIo s(&e, &en, cfg());
  s.start(true, 0);
  e.active = true;
  e.edges.push_back({true, 1 * kMs});
  s.update(1 * kMs);
  ASSERT_NE(s.requestReset(2 * kMs), nullptr);
  EXPECT_NE(std::string(s.requestReset(2 * kMs)).find("still pressed"), std::string::npos);
  e.active = false;
  e.edges.push_back({false, 50 * kMs});
  s.update(55 * kMs);
  const char* why = s.requestReset(60 * kMs);  // 10 ms after the release edge: bounce window
  ASSERT_NE(why, nullptr);
  EXPECT_NE(std::string(why).find("debounce"), std::string::npos);
  // A bounce (press edge) restarts the window.
  e.edges.push_back({true, 65 * kMs});
  e.edges.push_back({false, 66 * kMs});
  s.update(67 * kMs);
  EXPECT_NE(s.requestReset(80 * kMs), nullptr);
  EXPECT_EQ(s.requestReset(90 * kMs), nullptr);
  EXPECT_EQ(s.counters().resets_refused, 4u);
  EXPECT_FALSE(en.level) << "the enable line rises at the next update, not before";
  s.update(90 * kMs);
  EXPECT_TRUE(en.level);
}

TEST(SafetyIo, ALostLineCountsAsPressedAndIsReopened) {
  MockEstop e;
  MockOutput en;
  SafetyIo s(&e, &en, cfg());
  s.start(true, 0);
  e.lost = true;
  EXPECT_TRUE(s.update(5 * kMs));
  EXPECT_EQ(s.cause(), StopCause::kEstopLineLost);
  EXPECT_TRUE(s.estopPressed());
  EXPECT_FALSE(en.level);
  EXPECT_NE(std::string(s.requestReset(6 * kMs)).find("lost"), std::string::npos);
  // Re-opened at most once per interval.
  s.update(500 * kMs);
  EXPECT_EQ(e.reopens, 0);
  s.update(1005 * kMs);
  EXPECT_EQ(e.reopens, 1);
  e.reopen_ok = true;
  s.update(1500 * kMs);
  EXPECT_EQ(e.reopens, 1);
  s.update(2010 * kMs);
  EXPECT_EQ(e.reopens, 2);
  EXPECT_TRUE(s.estopLineOk());
  EXPECT_FALSE(s.estopPressed());
  EXPECT_NE(s.requestReset(2015 * kMs), nullptr) << "released only 5 ms ago";
  EXPECT_EQ(s.requestReset(2031 * kMs), nullptr);
}

TEST(SafetyIo, AnUnopenableOrPressedLineAtStartStartsStopped) {
  MockEstop e;
  MockOutput en;
  SafetyIo a(&e, &en, cfg());
  a.start(false, 0);
  EXPECT_TRUE(a.stopped());
  EXPECT_EQ(a.cause(), StopCause::kEstopLineLost);
  EXPECT_FALSE(en.level);
  MockEstop p;
  p.active = true;
  MockOutput en2;
  SafetyIo b(&p, &en2, cfg());
  b.start(true, 0);
  EXPECT_TRUE(b.stopped());
  EXPECT_EQ(b.cause(), StopCause::kPressedAtStart);
  EXPECT_FALSE(en2.level);
}

TEST(SafetyIo, AFailedEnableWriteStopsAndIsRefreshed) {
  MockEstop e;
  MockOutput en;
  SafetyIo s(&e, &en, cfg());
  s.start(true, 0);
  const int writes = en.writes;
  s.update(5 * kMs);
  EXPECT_EQ(en.writes, writes) << "no write before the refresh interval";
  s.update(11 * kMs);
  EXPECT_EQ(en.writes, writes + 1) << "re-written every refresh interval: a lost line is found";
  en.fail = true;
  EXPECT_TRUE(s.update(22 * kMs));
  EXPECT_EQ(s.cause(), StopCause::kEnableLineFailed);
  EXPECT_NE(std::string(s.requestReset(100 * kMs)).find("enable"), std::string::npos);
  en.fail = false;
  s.update(110 * kMs);  // the refresh writes "inactive" successfully: the line is back
  EXPECT_EQ(s.requestReset(120 * kMs), nullptr);
  s.update(120 * kMs);
  EXPECT_TRUE(en.level);
}

TEST(SafetyIo, WithoutAnEstopOnlyTheEnableLineIsDriven) {
  MockOutput en;
  SafetyIo s(nullptr, &en, cfg());
  s.start(false, 0);
  EXPECT_FALSE(s.stopped());
  EXPECT_TRUE(en.level);
  s.shutdown();
  EXPECT_FALSE(en.level);
}

TEST(GpioLineSpec, ParsesChipLineAndActiveLow) {
  phalanx::linux_hal::GpioLineSpec l;
  EXPECT_EQ(phalanx::linux_hal::parseGpioLine("gpiochip0:5", l), "");
  EXPECT_EQ(l.chip, "gpiochip0");
  EXPECT_EQ(l.offset, 5u);
  EXPECT_FALSE(l.active_low);
  EXPECT_EQ(phalanx::linux_hal::parseGpioLine("/dev/gpiochip1:12:active-low", l), "");
  EXPECT_EQ(l.chip, "/dev/gpiochip1");
  EXPECT_EQ(l.offset, 12u);
  EXPECT_TRUE(l.active_low);
  double hz = 0;
  EXPECT_EQ(phalanx::linux_hal::parseGpioSync("phx-io:1@480", l, hz), "");
  EXPECT_EQ(l.chip, "phx-io");
  EXPECT_EQ(hz, 480.0);
}

TEST(GpioLineSpec, RejectsMalformedSpecsNamingTheProblem) {
  phalanx::linux_hal::GpioLineSpec l;
  double hz = 0;
  EXPECT_NE(phalanx::linux_hal::parseGpioLine("gpiochip0", l).find("CHIP:LINE"), std::string::npos);
  EXPECT_NE(phalanx::linux_hal::parseGpioLine(":3", l).find("CHIP:LINE"), std::string::npos);
  EXPECT_NE(phalanx::linux_hal::parseGpioLine("gpiochip0:x", l).find("line 'x'"), std::string::npos);
  EXPECT_NE(phalanx::linux_hal::parseGpioLine("gpiochip0:-1", l).find("line '-1'"), std::string::npos);
  EXPECT_NE(phalanx::linux_hal::parseGpioSync("gpiochip0:2", l, hz).find("CHIP:LINE@HZ"), std::string::npos);
  EXPECT_NE(phalanx::linux_hal::parseGpioSync("gpiochip0:2@0", l, hz).find("rate '0'"), std::string::npos);
  EXPECT_NE(phalanx::linux_hal::parseGpioSync("gpiochip0:2@5000", l, hz).find("rate '5000'"), std::string::npos);
  EXPECT_NE(phalanx::linux_hal::parseGpioSync("gpiochip0:2@nan", l, hz).find("rate"), std::string::npos);
}

TEST(GpioOptions, ValidateNamesTheOptionAndRefusesSharedLines) {
  phalanx::host::RunOptions o;
  o.gpio.estop = "gpiochip0:x";
  EXPECT_NE(phalanx::host::validate(o).find("gpio.estop"), std::string::npos);
  o.gpio.estop = "gpiochip0:1";
  o.gpio.enable = "gpiochip0:1";
  EXPECT_NE(phalanx::host::validate(o).find("same line"), std::string::npos);
  o.gpio.enable = "gpiochip0:2";
  o.gpio.sync = "gpiochip0:3@480";
  EXPECT_EQ(phalanx::host::validate(o), "");
  o.gpio.estop_release_ms = 0.0;
  EXPECT_NE(phalanx::host::validate(o).find("estop_release_ms"), std::string::npos);
}

TEST(GpioEstopInput, AChipThatCannotBeOpenedReadsAsLost) {
  // This machine has no GPIO chips (and any CI runner lacks this one): the real libgpiod path fails to open.
  phalanx::linux_hal::GpioEstopInput in;
  phalanx::linux_hal::GpioLineSpec l;
  ASSERT_EQ(phalanx::linux_hal::parseGpioLine("no-such-gpio-chip-phalanx:0", l), "");
  EXPECT_NE(in.open(l, "test"), "");
  EXPECT_FALSE(in.isOpen());
  const EstopSample s = in.poll();
  EXPECT_FALSE(s.ok);
  EXPECT_FALSE(in.reopen());
  phalanx::linux_hal::GpioOutput out;
  EXPECT_NE(out.open(l, "test"), "");
  EXPECT_FALSE(out.write(true));
}

TEST(GpioOptions, ConfigFileKeysAreReadAndValidated) {
  phalanx::host::RunOptions o;
  EXPECT_EQ(phalanx::host::loadConfigText("gpio:\n  estop: gpiochip0:1:active-low\n  enable: gpiochip0:2\n"
                                          "  sync: gpiochip0:3@480\n  estop_release_ms: 50\n",
                                          "test.yaml", o),
            "");
  EXPECT_EQ(o.gpio.estop, "gpiochip0:1:active-low");
  EXPECT_EQ(o.gpio.enable, "gpiochip0:2");
  EXPECT_EQ(o.gpio.sync, "gpiochip0:3@480");
  EXPECT_EQ(o.gpio.estop_release_ms, 50.0);
  phalanx::host::RunOptions p;
  const std::string err = phalanx::host::loadConfigText("gpio:\n  sync: gpiochip0:3@2000\n", "test.yaml", p);
  EXPECT_NE(err.find("gpio.sync"), std::string::npos) << err;
  EXPECT_EQ(p.gpio.sync, "") << "nothing changes unless the whole file is valid";
  EXPECT_NE(phalanx::host::loadConfigText("gpio:\n  reset: gpiochip0:4\n", "test.yaml", p).find("gpio.reset: unknown key"),
            std::string::npos);
}
