// Geometry files written by the design tools, consumed by the controller configuration (phalanxd / phalanx run):
// the files change the model the controller uses, bad files are refused by name, and the geometry fingerprint
// the host will demand equals the one the firmware reports for its compile-time geometry.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <string>
#include <unistd.h>

#include "phalanx/apps/glove5.h"
#include "phalanx/apps/pantograph.h"
#include "phalanx/geometry_fingerprint.h"
#include "phalanx/host/config.h"
#include "phalanx/host/daemon.h"
#include "phalanx/host/design/glove_design.h"
#include "phalanx/host/design/pen_geometry.h"
#include "phalanx/host/glove/glove_controller.h"
#include "phalanx/host/pen/pen_controller.h"
#include "phalanx/protocol/devices.h"

namespace phalanx::host {
// host/src/controllers.cpp (declared where the daemon uses it).
std::unique_ptr<Controller> makeController(const protocol::DeviceLayout& layout, const RunOptions& opt,
                                           std::string& error);
}  // namespace phalanx::host

namespace {

using namespace phalanx;
namespace d = phalanx::host::design;

std::string tmpPath(const std::string& name) {
  return "/tmp/phalanx_geometry_test_" + std::to_string(::getpid()) + "_" + name;
}

std::string writeFile(const std::string& name, const std::string& text) {
  const std::string p = tmpPath(name);
  std::ofstream(p) << text;
  return p;
}

// Table VII's 25 cm design, as `phalanx design pen-gii --yaml` writes it.
std::string writeTable7Pen() {
  const pen::Geometry<double> g{0.024, 0.17, 0.23, 0.08, 0.07, 0.25};
  return writeFile("pen25.yaml", d::penGeometryYaml(g, "test", {{"gii", 0.2353}}));
}

std::unique_ptr<host::Controller> controllerFor(const protocol::DeviceLayout& layout, const std::string& config_yaml,
                                                std::string& error) {
  host::RunOptions opt;
  error = host::loadConfigText(config_yaml, "test.yaml", opt);
  if (!error.empty()) return nullptr;
  return host::makeController(layout, opt, error);
}

TEST(GeometryConfig, PenGeometryFileFromTheDesignToolChangesThePenControllersModel) {
  const std::string path = writeTable7Pen();
  std::string err;
  auto ctl = controllerFor(protocol::kPantographLayout, "device: sim:pantograph\npen:\n  geometry: " + path + "\n", err);
  ASSERT_TRUE(ctl) << err;
  const auto* pc = dynamic_cast<const host::pen::PenController*>(ctl.get());
  ASSERT_NE(pc, nullptr);
  const pen::Model<double>& m = pc->model();
  const pen::Model<double> def = pen::defaultModel<double>();
  EXPECT_DOUBLE_EQ(m.pantograph[0].l2_m, 0.17);
  EXPECT_DOUBLE_EQ(m.pantograph[1].l3_m, 0.23);
  EXPECT_DOUBLE_EQ(m.home_centre_m[2], 0.25);
  EXPECT_NE(m.pantograph[0].l2_m, def.pantograph[0].l2_m);
  EXPECT_GT(std::fabs(m.q_home_rad[1] - def.q_home_rad[1]), 0.01);  // home joint angles follow the geometry
  // The file's geometry is not the firmware's: the controller demands the file's fingerprint.
  const auto req = ctl->requiredParams();
  ASSERT_EQ(req.size(), 1u);
  EXPECT_EQ(req[0].id, apps::pantograph_param::kGeometryFingerprint);
  EXPECT_EQ(req[0].value, static_cast<float>(geometryFingerprint(pen::Geometry<double>{0.024, 0.17, 0.23, 0.08, 0.07, 0.25})));
  EXPECT_NE(req[0].what.find(path), std::string::npos);
  apps::PantographApp fw;
  float fw_value = 0.0f;
  ASSERT_EQ(fw.getParam(apps::pantograph_param::kGeometryFingerprint, fw_value), protocol::ParamStatus::kOk);
  EXPECT_NE(fw_value, req[0].value);  // the daemon will refuse this pair (tests/integration/geometry_file_test)
  std::remove(path.c_str());
}

TEST(GeometryConfig, DefaultPenGeometryFileMatchesTheFirmwaresFingerprint) {
  const std::string path = writeFile("pen20.yaml", d::penGeometryYaml(pen::defaultGeometry<double>(), "default"));
  host::RunOptions opt;
  opt.pen_geometry = path;
  std::string err;
  auto ctl = host::makeController(protocol::kPantographLayout, opt, err);
  ASSERT_TRUE(ctl) << err;
  apps::PantographApp fw;
  float fw_value = 0.0f;
  ASSERT_EQ(fw.getParam(apps::pantograph_param::kGeometryFingerprint, fw_value), protocol::ParamStatus::kOk);
  ASSERT_EQ(ctl->requiredParams().size(), 1u);
  EXPECT_EQ(ctl->requiredParams()[0].value, fw_value);
  EXPECT_EQ(fw.setParam(apps::pantograph_param::kGeometryFingerprint, fw_value), protocol::ParamStatus::kReadOnly);
  // Without a file nothing is demanded (the compile-time default on both sides).
  host::RunOptions none;
  auto ctl2 = host::makeController(protocol::kPantographLayout, none, err);
  ASSERT_TRUE(ctl2);
  EXPECT_TRUE(ctl2->requiredParams().empty());
  std::remove(path.c_str());
}

TEST(GeometryConfig, GloveGeometryFileFromTheDesignToolChangesTheGloveControllersFinger) {
  glove::Model<double> m = glove::defaultModel<double>(glove::FingerId::kIndex);
  m.mech.l1_m = 0.07105;
  m.mech.l2_m = 0.05016;
  const d::GloveAnalysis a = d::analyseGlove(m, d::SweepGrid{{5, 5, 5}});
  const std::string path = writeFile("index.yaml", d::gloveGeometryYaml(m, a, "test"));
  std::string err;
  auto ctl = controllerFor(protocol::kGlove5Layout, "glove:\n  geometry:\n    index: " + path + "\n", err);
  ASSERT_TRUE(ctl) << err;
  const auto* gc = dynamic_cast<const host::glove::GloveController*>(ctl.get());
  ASSERT_NE(gc, nullptr);
  const auto idx = static_cast<std::size_t>(glove::FingerId::kIndex);
  EXPECT_NEAR(gc->hand().fingers[idx].mech.l1_m, 0.07105, 1e-9);
  EXPECT_NEAR(gc->hand().fingers[idx].mech.l2_m, 0.05016, 1e-9);
  const auto mid = static_cast<std::size_t>(glove::FingerId::kMiddle);
  EXPECT_EQ(gc->hand().fingers[mid].mech.l1_m, glove::defaultModel<double>(glove::FingerId::kMiddle).mech.l1_m);
  const auto req = ctl->requiredParams();
  ASSERT_EQ(req.size(), 1u);
  EXPECT_EQ(req[0].id, apps::glove5_param::kGeometryFingerprintBase + idx);
  // The glove firmware reports the fingerprint of its calibration's mechanism: the default, not this file.
  apps::Glove5App fw(apps::glove5DefaultCalibration(), apps::glove5DefaultConfig());
  float fw_value = 0.0f;
  ASSERT_EQ(fw.getParam(static_cast<uint16_t>(apps::glove5_param::kGeometryFingerprintBase + idx), fw_value),
            protocol::ParamStatus::kOk);
  EXPECT_EQ(fw_value, static_cast<float>(geometryFingerprint(glove::defaultModel<float>(glove::FingerId::kIndex).mech)));
  EXPECT_NE(fw_value, req[0].value);
  std::remove(path.c_str());
}

TEST(GeometryConfig, BadGeometryFilesAreRefusedByName) {
  auto refuse = [](const std::string& config, const std::vector<std::string>& needles) {
    host::RunOptions opt;
    const std::string err = host::loadConfigText(config, "cfg.yaml", opt);
    EXPECT_FALSE(err.empty()) << config;
    for (const std::string& n : needles) EXPECT_NE(err.find(n), std::string::npos) << err << " lacks " << n;
  };
  const std::string good = d::penGeometryYaml(pen::defaultGeometry<double>(), "x");
  auto edit = [&](const std::string& from, const std::string& to) {
    std::string s = good;
    const auto at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    s.replace(at, from.size(), to);
    return s;
  };
  const std::string missing = tmpPath("does_not_exist.yaml");
  refuse("pen:\n  geometry: " + missing + "\n", {"pen.geometry", missing, "cannot read"});
  const std::string unknown = writeFile("unknown.yaml", edit("l1_m:", "l7_m: 0.01\n  l1_m:"));
  refuse("pen:\n  geometry: " + unknown + "\n", {"pen.geometry", unknown, "pen_geometry.l7_m", "unknown key"});
  const std::string negative = writeFile("negative.yaml", edit("l2_m: 0.145", "l2_m: -0.145"));
  refuse("pen:\n  geometry: " + negative + "\n", {negative, "pen_geometry.l2_m", "> 0"});
  const std::string text = writeFile("text.yaml", edit("l3_m: 0.2", "l3_m: long"));
  refuse("pen:\n  geometry: " + text + "\n", {text, "pen_geometry.l3_m", "number"});
  const std::string cm = writeFile("cm.yaml", edit("l3_m: 0.2", "l3_m: 20"));
  refuse("pen:\n  geometry: " + cm + "\n", {cm, "pen_geometry.l3_m", "metres"});
  const std::string far = writeFile("far.yaml", edit("home_z_m: 0.2", "home_z_m: 0.5"));
  refuse("pen:\n  geometry: " + far + "\n", {far, "home pose", "unreachable"});
  const std::string oldreading = writeFile("reading.yaml", edit("centre to universal joint (pen length 2 l6)", "pen length"));
  refuse("pen:\n  geometry: " + oldreading + "\n", {oldreading, "pen_geometry.l6_reading"});
  const std::string twice = writeFile("twice.yaml", edit("l2_m: 0.145", "l2_m: 0.145\n  l2_m: 0.17"));
  refuse("pen:\n  geometry: " + twice + "\n", {"pen.geometry", twice, "pen_geometry.l2_m: duplicate key"});
  // A glove file given as a pen geometry, and a pen file given as a glove finger.
  glove::Model<double> gm = glove::defaultModel<double>(glove::FingerId::kIndex);
  const std::string glovefile = writeFile("glove.yaml", d::gloveGeometryYaml(gm, d::analyseGlove(gm, d::SweepGrid{{3, 3, 3}}), "g"));
  refuse("pen:\n  geometry: " + glovefile + "\n", {glovefile, "glove finger geometry", "not a pen geometry"});
  const std::string penfile = writeFile("pen.yaml", good);
  refuse("glove:\n  geometry:\n    index: " + penfile + "\n", {"glove.geometry.index", penfile, "glove_finger_geometry"});
  refuse("glove:\n  geometry:\n    toe: " + glovefile + "\n", {"glove.geometry.toe", "unknown key"});
  refuse("pen:\n  geometri: " + penfile + "\n", {"pen.geometri", "unknown key"});
  // A geometry file for another device type is refused, never ignored.
  host::RunOptions opt;
  opt.pen_geometry = penfile;
  std::string err;
  EXPECT_EQ(host::makeController(protocol::kGlove5Layout, opt, err), nullptr);
  EXPECT_NE(err.find("pen.geometry"), std::string::npos) << err;
  EXPECT_NE(err.find("glove5"), std::string::npos) << err;
  for (const std::string& p : {unknown, negative, text, cm, far, oldreading, twice, glovefile, penfile}) std::remove(p.c_str());
}

TEST(GeometryConfig, FingerprintIsTheSameInFloatAndDoubleAndSeesEveryLength) {
  const pen::Geometry<double> g = pen::defaultGeometry<double>();
  EXPECT_EQ(geometryFingerprint(g), geometryFingerprint(pen::defaultGeometry<float>()));
  EXPECT_LT(geometryFingerprint(g), 1u << 24);
  for (int k = 0; k < 6; ++k) {
    pen::Geometry<double> h = g;
    double* f[] = {&h.l1_m, &h.l2_m, &h.l3_m, &h.l4_m, &h.l6_m, &h.home_z_m};
    *f[k] += 0.0001;  // 0.1 mm
    EXPECT_NE(geometryFingerprint(h), geometryFingerprint(g)) << k;
  }
  for (int f = 0; f < 5; ++f) {
    EXPECT_EQ(geometryFingerprint(glove::defaultModel<double>(static_cast<glove::FingerId>(f)).mech),
              geometryFingerprint(glove::defaultModel<float>(static_cast<glove::FingerId>(f)).mech));
  }
}

}  // namespace
