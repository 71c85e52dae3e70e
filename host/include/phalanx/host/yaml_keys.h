#pragma once
/// Checks every YAML file the host reads (configuration, patient profiles, geometry files, bench plans, SEA subject
/// files) shares before its loader looks up a key. yaml-cpp keeps both entries of a repeated mapping key and a
/// lookup returns one of them (the first with node[key], the last when a loader iterates and overwrites), so
/// `rate_hz: 100` followed by `rate_hz: 4000` would silently mean one or the other. Refuse it instead.
#include <yaml-cpp/yaml.h>

#include <string>

#include <nlohmann/json.hpp>

namespace phalanx::host {

/// The first repeated mapping key anywhere in node (in document order) as "<path>: duplicate key (line L; first at
/// line F)" with the key's full path ("limits.effort_max.index", "steps[2].kind"); "" when every mapping's keys are
/// distinct. Keys are compared by their text, as the loaders read them. A document nested deeper than
/// kMaxYamlDepth (a self-referencing alias is endlessly deep) or with more than kMaxYamlNodes nodes once its
/// aliases are expanded is refused too, by path, since it cannot be checked.
std::string findDuplicateKey(const YAML::Node& node);

/// A YAML node as JSON: mappings, lists, and scalars as whole numbers, numbers, true/false or strings (a quoted
/// scalar stays a string; a null is null). Used where a YAML file carries what the API takes as JSON (session
/// plans of `phalanx start --plan FILE` and of a profile's `plans:`); the JSON's reader validates the fields.
nlohmann::json yamlToJson(const YAML::Node& n);

inline constexpr int kMaxYamlDepth = 64;
inline constexpr long kMaxYamlNodes = 1000000;

}  // namespace phalanx::host
