// A pen geometry YAML written by `phalanx design pen-gii --yaml` is consumed by `phalanx run --pen-geometry`
// (and the config key pen.geometry): a file matching the firmware's compile-time geometry runs and the summary
// names it; a different geometry is refused (the firmware's fingerprint differs); a bad file is refused by name.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <cstdio>
#include <fstream>

#include "process.h"

using phalanx::test::binPath;
using phalanx::test::Process;

namespace {

std::string tmp(const std::string& n) { return "/tmp/phalanx_geofile_" + std::to_string(::getpid()) + "_" + n; }

// Writes the geometry (cm) through the design tool; a one-sample search so that the tool is fast.
void designPen(const std::string& path, const char* dist, const char* l2, const char* l3) {
  Process p({binPath("phalanx"), "design", "pen-gii", "--distance-cm", dist, "--l1", "2.4:2.4:1", "--l2",
             std::string(l2) + ":" + l2 + ":1", "--l3", std::string(l3) + ":" + l3 + ":1", "--l6", "7:7:1", "--q1",
             "1.6:1.6:1", "--wi", "0:0:1", "--wj", "0:0:1", "--wk", "0:0:1", "--rings", "1", "--yaml", path});
  ASSERT_EQ(p.wait(60000), 0) << p.stderrText();
}

TEST(GeometryFile, DesignToolPenGeometryRunsWhenItMatchesTheFirmwareAndIsRefusedOtherwise) {
  const std::string same = tmp("pen20.yaml"), other = tmp("pen25.yaml"), cfg = tmp("cfg.yaml");
  designPen(same, "20", "14.5", "20");   // Table VIII 20 cm = the firmware's pen::defaultGeometry
  designPen(other, "25", "17", "23");    // Table VII 25 cm design
  {
    Process run({binPath("phalanx"), "run", "--device", "sim:pantograph", "--pen-geometry", same, "--seconds", "0.3",
                 "--json", "--no-realtime", "--firmware-sim", binPath("firmware-sim")});
    ASSERT_EQ(run.wait(60000), 0) << run.stderrText();
    const auto s = nlohmann::json::parse(run.stdoutText());
    EXPECT_EQ(s["pantograph"]["pen"]["geometry_file"], same);
    EXPECT_DOUBLE_EQ(s["pantograph"]["pen"]["geometry_m"]["l2"].get<double>(), 0.145);
  }
  {
    std::ofstream(cfg) << "device: sim:pantograph\nseconds: 0.3\npen:\n  geometry: " << other << "\n";
    Process run({binPath("phalanx"), "run", "--config", cfg, "--json", "--no-realtime", "--firmware-sim",
                 binPath("firmware-sim")});
    EXPECT_EQ(run.wait(60000), 2);
    const std::string err = run.stderrText();
    EXPECT_NE(err.find(other), std::string::npos) << err;
    EXPECT_NE(err.find("differs from the firmware's compile-time geometry"), std::string::npos) << err;
  }
  {
    std::ofstream(cfg) << "device: sim:pantograph\nseconds: 0.3\npen:\n  geometry: " << tmp("nope.yaml") << "\n";
    Process run({binPath("phalanx"), "run", "--config", cfg, "--json", "--no-realtime"});
    EXPECT_NE(run.wait(60000), 0);
    const std::string err = run.stderrText();
    EXPECT_NE(err.find("pen.geometry"), std::string::npos) << err;
    EXPECT_NE(err.find(tmp("nope.yaml")), std::string::npos) << err;
  }
  for (const std::string& p : {same, other, cfg}) std::remove(p.c_str());
}

}  // namespace
