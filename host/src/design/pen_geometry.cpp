#include "phalanx/host/design/pen_geometry.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <set>

#include "phalanx/host/yaml_keys.h"

namespace phalanx::host::design {

namespace {
constexpr const char* kL6Reading = "centre to universal joint (pen length 2 l6)";
}

std::string penGeometryYaml(const pen::Geometry<double>& g, const std::string& comment,
                            const std::map<std::string, double>& analysis) {
  YAML::Emitter e;
  e.SetDoublePrecision(10);
  e << YAML::Comment(comment);
  e << YAML::BeginMap << YAML::Key << "pen_geometry" << YAML::Value << YAML::BeginMap;
  e << YAML::Key << "units" << YAML::Value << "m";
  e << YAML::Key << "l6_reading" << YAML::Value << kL6Reading;
  e << YAML::Key << "l1_m" << YAML::Value << g.l1_m;
  e << YAML::Key << "l2_m" << YAML::Value << g.l2_m;
  e << YAML::Key << "l3_m" << YAML::Value << g.l3_m;
  e << YAML::Key << "l4_m" << YAML::Value << g.l4_m;
  e << YAML::Key << "l6_m" << YAML::Value << g.l6_m;
  e << YAML::Key << "home_z_m" << YAML::Value << g.home_z_m;
  if (!analysis.empty()) {
    e << YAML::Key << "analysis" << YAML::Value << YAML::BeginMap;
    for (const auto& [k, v] : analysis) e << YAML::Key << k << YAML::Value << v;
    e << YAML::EndMap;
  }
  e << YAML::EndMap << YAML::EndMap;
  return std::string(e.c_str()) + "\n";
}

std::string loadPenGeometryYaml(const std::string& path, pen::Geometry<double>& out) {
  std::ifstream in(path);
  std::stringstream text;
  if (!in || !(text << in.rdbuf())) return path + ": cannot read pen geometry file";
  return loadPenGeometryText(text.str(), path, out);
}

std::string loadPenGeometryText(const std::string& yaml_text, const std::string& path, pen::Geometry<double>& out) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& ex) {
    return path + ": YAML syntax error at line " + std::to_string(ex.mark.line + 1) + ": " + ex.msg;
  }
  if (std::string dup = findDuplicateKey(root); !dup.empty()) return path + ": " + dup;
  if (root.IsMap() && root["glove_finger_geometry"]) {
    return path + ": is a glove finger geometry (glove_finger_geometry), not a pen geometry";
  }
  if (!root.IsMap() || !root["pen_geometry"]) return path + ": missing 'pen_geometry'";
  const YAML::Node g = root["pen_geometry"];
  if (!g.IsMap()) return path + ": pen_geometry: expected a mapping";
  const std::set<std::string> allowed{"units", "l6_reading", "l1_m", "l2_m", "l3_m", "l4_m", "l6_m", "home_z_m",
                                      "analysis"};
  for (const auto& kv : g) {
    if (!kv.first.IsScalar()) return path + ": pen_geometry: every key must be a plain name";
    const std::string key = kv.first.Scalar();
    if (allowed.count(key) == 0) return path + ": pen_geometry." + key + ": unknown key";
  }
  if (!g["units"] || !g["units"].IsScalar() || g["units"].Scalar() != "m") {
    return path + ": pen_geometry.units: must be 'm'";
  }
  if (g["l6_reading"] && (!g["l6_reading"].IsScalar() || g["l6_reading"].Scalar() != kL6Reading)) {
    return path + ": pen_geometry.l6_reading: this controller reads l6 as '" + kL6Reading + "'";
  }
  pen::Geometry<double> geo{};
  const std::pair<const char*, double*> fields[] = {{"l1_m", &geo.l1_m}, {"l2_m", &geo.l2_m}, {"l3_m", &geo.l3_m},
                                                    {"l4_m", &geo.l4_m}, {"l6_m", &geo.l6_m}, {"home_z_m", &geo.home_z_m}};
  for (const auto& [key, dst] : fields) {
    const YAML::Node n = g[key];
    if (!n) return path + ": pen_geometry." + key + ": missing";
    double v = 0.0;
    try {
      if (!n.IsScalar()) throw YAML::Exception(YAML::Mark::null_mark(), "not a scalar");
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      return path + ": pen_geometry." + key + ": expected a number (metres)";
    }
    if (!std::isfinite(v) || !(v > 0.0)) return path + ": pen_geometry." + key + ": must be a finite length > 0 m";
    if (v > 2.0) return path + ": pen_geometry." + key + ": " + std::to_string(v) + " m is not a pen (units are metres)";
    *dst = v;
  }
  pen::Model<double> m;
  const pen::Status s = pen::makeModel(geo, m);
  if (s != pen::Status::kOk) {
    return path + ": pen_geometry: the lengths do not make a pen that reaches its home pose (0, 0, home_z_m) " +
           (s == pen::Status::kUnreachable ? "(unreachable)" : "(singular or inconsistent at home)");
  }
  out = geo;
  return "";
}

}  // namespace phalanx::host::design
