#include "phalanx/host/yaml_keys.h"

#include <map>

namespace phalanx::host {
namespace {

std::string keyText(const YAML::Node& key) {
  if (key.IsScalar()) return key.Scalar();
  if (key.IsNull()) return "~";
  YAML::Emitter e;
  e << YAML::Flow << key;
  return e.c_str();
}

std::string lineOf(const YAML::Node& n) {
  const int line = n.Mark().line;
  return line >= 0 ? std::to_string(line + 1) : std::string("?");
}

std::string join(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }

class DuplicateKeyWalk {
 public:
  std::string check(const YAML::Node& node, const std::string& path, int depth) {
    if (depth > kMaxYamlDepth) return where(path) + ": nested deeper than " + std::to_string(kMaxYamlDepth) + " levels";
    if (++nodes_ > kMaxYamlNodes) return where(path) + ": more than " + std::to_string(kMaxYamlNodes) + " nodes";
    if (node.IsMap()) return checkMap(node, path, depth);
    if (node.IsSequence()) {
      for (std::size_t i = 0; i < node.size(); ++i) {
        if (std::string err = check(node[i], path + "[" + std::to_string(i) + "]", depth + 1); !err.empty()) return err;
      }
    }
    return {};
  }

 private:
  static std::string where(const std::string& path) { return path.empty() ? "top level" : path; }

  std::string checkMap(const YAML::Node& map, const std::string& path, int depth) {
    std::map<std::string, std::string> first_line;  // key → line of its first occurrence
    for (const auto& kv : map) {
      const std::string key = keyText(kv.first);
      // A list or mapping as a key ("? [a, b]: 1") names nothing a loader knows; the loaders read keys as
      // strings, which yaml-cpp cannot convert it to (it threw out of the geometry loaders).
      if (kv.first.IsSequence() || kv.first.IsMap()) {
        return join(path, key) + ": a key must be a plain name, not a list or mapping (line " + lineOf(kv.first) + ")";
      }
      const auto [it, fresh] = first_line.emplace(key, lineOf(kv.first));
      if (!fresh) {
        return join(path, key) + ": duplicate key (line " + lineOf(kv.first) + "; first at line " + it->second + ")";
      }
      if (std::string err = check(kv.second, join(path, key), depth + 1); !err.empty()) return err;
    }
    return {};
  }

  long nodes_ = 0;
};

}  // namespace

std::string findDuplicateKey(const YAML::Node& node) { return DuplicateKeyWalk{}.check(node, "", 0); }

nlohmann::json yamlToJson(const YAML::Node& n) {
  if (n.IsMap()) {
    nlohmann::json j = nlohmann::json::object();
    for (const auto& kv : n) j[kv.first.as<std::string>()] = yamlToJson(kv.second);
    return j;
  }
  if (n.IsSequence()) {
    nlohmann::json j = nlohmann::json::array();
    for (const auto& e : n) j.push_back(yamlToJson(e));
    return j;
  }
  if (!n.IsScalar()) return nullptr;
  const std::string& s = n.Scalar();
  if (n.Tag() == "!") return s;  // quoted: a string
  long long i = 0;
  double d = 0.0;
  bool b = false;
  if (YAML::convert<long long>::decode(n, i)) return i;
  if (YAML::convert<double>::decode(n, d)) return d;
  if (YAML::convert<bool>::decode(n, b)) return b;
  return s;
}

}  // namespace phalanx::host
