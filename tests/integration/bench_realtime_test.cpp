// The bench runner in real time (docs/bench-runner.md "Real time"): `phalanx bench run` drives the simulated SEA
// rig as one session of the daemon's session runner over the pseudo-terminal, firmware-sim serving the rig's load
// cell as a Modbus amplifier in its own process (TCP on loopback, RTU on a pty pair), and an independent amplifier
// written on pymodbus (PyPI, tests/integration/scripted_amplifier.py) that serves a scripted signal, lies or hangs.
//
// What is asserted, none of it on wall-clock timing: the shipped plan's limits pass as in lockstep; the alignment
// recovers a delay firmware-sim adds in whole device ticks; a lying or hung instrument stops the plan and the
// device's own telemetry reports it safe within two device ticks of the decision.
#include <gtest/gtest.h>
#include <unistd.h>

#include <signal.h>

#include <algorithm>
#include <climits>
#include <memory>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "process.h"

using phalanx::test::binPath;
using phalanx::test::Process;

namespace {

std::string tmpPath(const std::string& what) { return "/tmp/phalanx_bench_rt_" + std::to_string(getpid()) + "_" + what; }

// max_stale_percent 25: a shared CI machine's vCPU is taken away for up to 10 ms at a time (firmware-sim's wake-up
// lateness p99 1-5 ms under SCHED_FIFO beside stress-ng), and the instrument's poll thread with it: 4-15 % of the
// device ticks then have no young sample. Stale ticks are never scored; the share is reported (samples_stale).
const char* kInstrument = R"(instrument:
  transport: TRANSPORT
  type: int32
  scale: 1.0e-5
  unit: N*m
  poll_hz: 500
  timeout_ms: 50
  stale_ms: 50
max_stale_percent: 25
safety:
  effort_max: 0.4
  instrument_silence_ms: 200
  disagreement_max: 0.05
  disagreement_ms: 100
)";

std::string replace(std::string s, const std::string& from, const std::string& to) {
  for (size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size())) s.replace(at, from.size(), to);
  return s;
}

struct BenchRun {
  int exit_code = INT_MIN;
  nlohmann::json result;
  std::string err;
};

/// `phalanx bench run PLAN` as a user runs it; the JSON summary from stdout.
BenchRun benchRun(const std::string& name, const std::string& plan_text) {
  const std::string plan = tmpPath(name + ".yaml"), report = tmpPath(name + ".html");
  std::ofstream(plan) << plan_text;
  Process p({binPath("phalanx"), "bench", "run", plan, "--report", report});
  BenchRun r;
  r.exit_code = p.wait(180000);
  r.err = p.stderrText();
  try {
    r.result = nlohmann::json::parse(p.stdoutText());
  } catch (const nlohmann::json::exception&) {
  }
  unlink(plan.c_str());
  unlink(report.c_str());
  return r;
}

std::string seaPlan(const std::string& transport, const std::string& extra, const std::string& steps) {
  return "version: 1\ndevice: sim:sea_rig\nseed: 3\n" + extra + replace(kInstrument, "TRANSPORT", transport) + "steps:\n" + steps;
}

const char* kSine = R"(  - name: sine 0.3 N*m
    kind: sea-rig-sine
    peak_Nm: 0.3
    hz: 0.5
    seconds: 6
    settle_s: 2
    limits:
      setpoint_vs_instrument: {nrmse_percent_max: 11.59, fidelity_percent_min: 97.7}
      estimate_vs_instrument: {nrmse_percent_max: 6.0}
)";

const char* kChirp = R"(  - name: chirp 0.15 N*m
    kind: sea-rig-chirp
    amplitude_Nm: 0.15
    f0_hz: 0.1
    fmax_hz: 10
    seconds: 10
    limits:
      setpoint_vs_instrument: {bandwidth_hz_min: 2.5}
)";

double delayOf(const nlohmann::json& step) { return step.at("alignment").at("delay_ms").get<double>(); }

TEST(BenchRealtimeTest, SeaRigPlanOverThePtyWithItsTcpInstrumentPassesTheLockstepLimits) {
  const BenchRun r = benchRun("tcp", seaPlan("tcp", "", std::string(kSine) + kChirp));
  ASSERT_EQ(r.exit_code, 0) << r.err << r.result.dump(2);
  EXPECT_EQ(r.result["mode"], "realtime");
  const nlohmann::json& session = r.result["session"];
  EXPECT_EQ(session["device_type"], "sea_finger");
  EXPECT_EQ(session["exit_code"], 0);
  // Every command went through the session's limits stage (none needed limiting here; the counters exist).
  EXPECT_EQ(session["commands"]["refused_by_host_limits"], 0);
  EXPECT_TRUE(session["link"]["instrument"].get<std::string>().find("modbus tcp 127.0.0.1:") != std::string::npos);
  for (const auto& step : r.result["steps"]) {
    EXPECT_TRUE(step["pass"]) << step.dump(2);
    EXPECT_TRUE(step["alignment"]["ok"]) << step.dump(2);
    EXPECT_TRUE(step["alignment"]["comparable_to_lockstep"]);
    // Truth served in the tick it belongs to: the delay is the link's and the poll's, a few ms at most.
    EXPECT_LT(std::fabs(delayOf(step)), 3.0) << step["alignment"].dump();
    EXPECT_GT(step["link"]["frames"].get<double>(), 0.9 * step["link"]["device_ticks"].get<double>());
  }
}

TEST(BenchRealtimeTest, SeaRigPlanWithItsRtuInstrumentOnAPtyPairPasses) {
  const BenchRun r = benchRun("rtu", seaPlan("rtu", "", kSine));
  ASSERT_EQ(r.exit_code, 0) << r.err << r.result.dump(2);
  EXPECT_TRUE(r.result["session"]["link"]["instrument"].get<std::string>().find("modbus rtu /dev/pts/") != std::string::npos);
  EXPECT_TRUE(r.result["steps"][0]["alignment"]["ok"]);
}

TEST(BenchRealtimeTest, TheAlignmentRecoversADelayTheInstrumentAdds) {
  // The same chirp without and with 7 ms added by firmware-sim (7 whole ticks): the estimates differ by 7 ms.
  const BenchRun base = benchRun("d0", seaPlan("tcp", "", kChirp));
  const BenchRun late = benchRun("d7", seaPlan("tcp", "sim_instrument_delay_ms: 7\n", kChirp));
  ASSERT_TRUE(base.result.contains("steps")) << base.err;
  ASSERT_TRUE(late.result.contains("steps")) << late.err;
  const nlohmann::json& a0 = base.result["steps"][0];
  const nlohmann::json& a7 = late.result["steps"][0];
  ASSERT_TRUE(a0["alignment"]["ok"]) << a0.dump(2);
  ASSERT_TRUE(a7["alignment"]["ok"]) << a7.dump(2);
  const double recovered = delayOf(a7) - delayOf(a0);
  const double u0 = a0["alignment"]["uncertainty_ms"].get<double>(), u7 = a7["alignment"]["uncertainty_ms"].get<double>();
  // ±1 ms (the issue's bound), or three times the uncertainty the two runs report when the machine's noise makes
  // them coarser than that: the check is against what the measurement itself says it resolves.
  const double tolerance = std::max(1.0, 3.0 * std::sqrt(u0 * u0 + u7 * u7));
  std::printf("alignment: %.3f ms without, %.3f ms with 7 ms added (± %.3f / %.3f): recovered %.3f ms (tolerance %.2f)\n",
              delayOf(a0), delayOf(a7), u0, u7, recovered, tolerance);
  EXPECT_NEAR(recovered, 7.0, tolerance);
  // Scored on aligned samples, the delayed instrument passes the same limits.
  EXPECT_TRUE(a7["pass"]) << a7.dump(2);
}

/// The scripted amplifier on pymodbus; its port.
struct Amplifier {
  explicit Amplifier(const std::vector<std::string>& args) {
    std::vector<std::string> argv = {"/usr/bin/env", "python3", std::string(PHALANX_SOURCE_DIR) + "/tests/integration/scripted_amplifier.py"};
    argv.insert(argv.end(), args.begin(), args.end());
    proc = std::make_unique<Process>(argv);
    const std::string line = proc->readStdoutLine(15000);
    if (line.rfind("PORT ", 0) == 0) port = line.substr(5);
  }
  ~Amplifier() {
    proc->signal(SIGKILL);
    proc->wait(5000);
  }
  std::unique_ptr<Process> proc;
  std::string port;
};

std::string externalPlan(const std::string& port) {
  return replace(seaPlan("tcp", "sim_instrument: false\n", kSine), "  transport: tcp\n",
                 "  transport: tcp\n  host: 127.0.0.1\n  port: " + port + "\n");
}

void expectSafetyStop(const BenchRun& r, const std::string& cause) {
  ASSERT_EQ(r.exit_code, 1) << r.err << r.result.dump(2);
  const nlohmann::json& step = r.result["steps"][0];
  ASSERT_TRUE(step.contains("safety_stop")) << step.dump(2);
  EXPECT_NE(step["safety_stop"].get<std::string>().find(cause), std::string::npos) << step["safety_stop"];
  EXPECT_TRUE(step["active_at_stop"]);  // the device was pushing when the runner stopped trusting the instrument
  // Safe, from the device's own telemetry, within two device ticks of the decision: the safe command goes out in the
  // next cycle and the firmware applies it in the tick that reads it.
  EXPECT_GE(step["ticks_to_safe"].get<int>(), 0) << step.dump(2);
  EXPECT_LE(step["ticks_to_safe"].get<int>(), 2) << step.dump(2);
}

TEST(BenchRealtimeTest, AnIndependentAmplifierThatReadsZeroWhileTheRigPushesStopsThePlanSafely) {
  Amplifier amp({"--value", "0"});
  ASSERT_FALSE(amp.port.empty()) << "pymodbus amplifier did not start (tools/setup.sh --test installs pymodbus): "
                                 << amp.proc->stderrText();
  const BenchRun r = benchRun("lying", externalPlan(amp.port));
  expectSafetyStop(r, "instrument disagrees with the device's estimate");
  // The client read the scripted value through its register map: the disagreement is the device's torque itself.
  EXPECT_GT(r.result["steps"][0]["safety"]["largest_disagreement"].get<double>(), 0.05);
}

TEST(BenchRealtimeTest, AnIndependentAmplifierThatHangsStopsThePlanSafely) {
  // It serves the rig's rest torque (0) for 1.2 s, then accepts requests and never answers them.
  Amplifier amp({"--value", "0", "--hang-after-s", "1.2"});
  ASSERT_FALSE(amp.port.empty()) << amp.proc->stderrText();
  // A plan that trusts its load cell near zero (the sine is small): only the silence can stop it.
  std::string plan = replace(externalPlan(amp.port), "peak_Nm: 0.3", "peak_Nm: 0.02");
  plan = replace(plan, "{nrmse_percent_max: 11.59, fidelity_percent_min: 97.7}", "{}");
  plan = replace(plan, "{nrmse_percent_max: 6.0}", "{}");
  const BenchRun r = benchRun("hung", plan);
  expectSafetyStop(r, "instrument silent");
}

TEST(BenchRealtimeTest, TheSamePlanOnASerialDeviceWithItsOwnAmplifier) {
  // A board as a lab has it: firmware-sim started apart from the bench on its own pseudo-terminal (the board's
  // serial port) with its load cell on Modbus TCP; the plan names `serial:` and the amplifier's address.
  Process board({binPath("firmware-sim"), "--device", "sea_rig", "--seed", "5", "--instrument", "tcp:0"});
  const std::string pty_line = board.readStdoutLine(10000), inst_line = board.readStdoutLine(10000);
  ASSERT_EQ(pty_line.rfind("PTY ", 0), 0u) << pty_line << board.stderrText();
  const auto colon = inst_line.find("127.0.0.1:");
  ASSERT_NE(colon, std::string::npos) << inst_line;
  const std::string port = inst_line.substr(colon + 10, inst_line.find(' ', colon) - colon - 10);
  std::string plan = replace(seaPlan("tcp", "device_type: sea_rig\n", kSine), "device: sim:sea_rig", "device: serial:" + pty_line.substr(4));
  plan = replace(plan, "  transport: tcp\n", "  transport: tcp\n  host: 127.0.0.1\n  port: " + port + "\n");
  const BenchRun r = benchRun("serial", plan);
  ASSERT_EQ(r.exit_code, 0) << r.err << r.result.dump(2);
  const nlohmann::json& step = r.result["steps"][0];
  EXPECT_TRUE(step["alignment"]["ok"]) << step.dump(2);
  EXPECT_EQ(step["link"]["device"], "serial:" + pty_line.substr(4));
  EXPECT_EQ(r.result["session"]["device_type"], "sea_finger");
  board.signal(SIGTERM);
  EXPECT_EQ(board.wait(10000), 0) << board.stderrText();
}

const char* kGlovePlan = R"(version: 1
device: sim:glove5
seed: 1
instrument: {type: int32, scale: 1.0e-5, unit: N, poll_hz: 500, timeout_ms: 50, stale_ms: 50}
max_stale_percent: 25
safety: {effort_max: 10, instrument_silence_ms: 200, disagreement_max: 1.5, disagreement_ms: 100}
steps:
  - kind: glove-grasp
    limits:
      setpoint_vs_instrument: {nrmse_percent_max: 10}
      estimate_vs_instrument: {nrmse_percent_max: 10}
)";

TEST(BenchRealtimeTest, GloveGraspPlanHoldsTheBallInRealTime) {
  // firmware-sim's hand reaches for the ball the session renders (scenario grasp) and its instrument serves the
  // index finger's true pad force. The held force does not fix a delay, so only the quarters that follow the
  // estimate (the reach) check it.
  const BenchRun r = benchRun("grasp", kGlovePlan);
  ASSERT_EQ(r.exit_code, 0) << r.err << r.result.dump(2);
  const nlohmann::json& step = r.result["steps"][0];
  EXPECT_EQ(step["kind"], "glove-grasp");
  EXPECT_TRUE(step["alignment"]["ok"]) << step.dump(2);
  EXPECT_GE(step["alignment"]["quarters_used"].get<int>(), 2);
  EXPECT_LT(std::fabs(delayOf(step)), 3.0) << step["alignment"].dump();
}

TEST(BenchRealtimeTest, PlansTheRealTimeRunCannotDoAreRefusedBeforeAnythingRuns) {
  const BenchRun pen = benchRun("pen", std::string("version: 1\ndevice: sim:pantograph\n") +
                                      replace(replace(kInstrument, "TRANSPORT", "tcp"), "effort_max: 0.4", "effort_max: 2.1") +
                                      "steps:\n  - kind: pen-wall\n    seconds: 2\n");
  EXPECT_EQ(pen.exit_code, 2);
  EXPECT_NE(pen.err.find("pen-wall runs in lockstep only"), std::string::npos) << pen.err;
  const BenchRun bad = benchRun("bad", seaPlan("tcp", "device_type: glove5\n", kSine));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("device_type: glove5 contradicts device sim:sea_rig"), std::string::npos) << bad.err;
  // firmware-sim's simulated hand runs one scenario per session.
  const BenchRun mixed = benchRun("mixed", std::string(kGlovePlan) + "  - kind: glove-free-motion\n    seconds: 2\n");
  EXPECT_EQ(mixed.exit_code, 2);
  EXPECT_NE(mixed.err.find("steps[1].kind: firmware-sim's simulated hand runs one scenario"), std::string::npos) << mixed.err;
}

}  // namespace
