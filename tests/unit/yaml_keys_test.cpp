// findDuplicateKey: the one check every YAML loader of the host runs before it reads a key (config, profiles,
// geometry files, bench plans, SEA subject files; each loader's own test shows it refuses a repeated key).
#include <gtest/gtest.h>

#include <string>

#include "phalanx/host/yaml_keys.h"

using phalanx::host::findDuplicateKey;

namespace {
std::string dup(const std::string& yaml) { return findDuplicateKey(YAML::Load(yaml)); }
}  // namespace

TEST(YamlKeys, DistinctKeysPass) {
  EXPECT_EQ(dup("a: 1\nb: {c: 2, d: [1, 2, {e: 3}]}\n"), "");
  EXPECT_EQ(dup(""), "");
  EXPECT_EQ(dup("[1, 1, 2]\n"), "");  // repeated values are not keys
}

TEST(YamlKeys, TheSameKeyInSiblingMappingsIsNotADuplicate) {
  EXPECT_EQ(dup("index: {p1_mm: 1}\nthumb: {p1_mm: 1}\nsteps: [{kind: a}, {kind: b}]\n"), "");
}

TEST(YamlKeys, ATopLevelDuplicateIsNamedWithBothLines) {
  EXPECT_EQ(dup("rate_hz: 100\nseed: 1\nrate_hz: 4000\n"), "rate_hz: duplicate key (line 3; first at line 1)");
}

TEST(YamlKeys, ANestedDuplicateIsNamedByItsFullPath) {
  EXPECT_EQ(dup("limits:\n  effort_max: {default: 2, index: 1, index: 9}\n"),
            "limits.effort_max.index: duplicate key (line 2; first at line 2)");
}

TEST(YamlKeys, ADuplicateInsideAListElementNamesTheIndex) {
  EXPECT_EQ(dup("steps:\n  - {kind: sea-rig-sine}\n  - kind: pen-wall\n    seconds: 1\n    seconds: 2\n"),
            "steps[1].seconds: duplicate key (line 5; first at line 4)");
}

TEST(YamlKeys, QuotingDoesNotMakeAKeyDifferent) {
  EXPECT_EQ(dup("a: 1\n'a': 2\n"), "a: duplicate key (line 2; first at line 1)");
}

TEST(YamlKeys, TheFirstDuplicateInDocumentOrderIsReported) {
  EXPECT_EQ(dup("g: {x: 1, x: 2}\ng: 3\n"), "g.x: duplicate key (line 1; first at line 1)");
}

TEST(YamlKeys, ASelfReferencingAliasIsRefusedInsteadOfWalkedForever) {
  const std::string err = dup("a: &loop [*loop]\n");
  EXPECT_NE(err.find("nested deeper than"), std::string::npos) << err;
  EXPECT_EQ(err.rfind("a[0][0]", 0), 0u) << err;
}

TEST(YamlKeys, AliasesThatExpandToMillionsOfNodesAreRefused) {
  std::string doc = "l0: &l0 [x, x, x, x, x, x, x, x, x, x]\n";
  for (int i = 1; i <= 6; ++i) {  // 10^7 leaves once expanded
    const std::string p = "*l" + std::to_string(i - 1);
    doc += "l" + std::to_string(i) + ": &l" + std::to_string(i) + " [" + p + "," + p + "," + p + "," + p + "," + p +
           "," + p + "," + p + "," + p + "," + p + "," + p + "]\n";
  }
  const std::string err = dup(doc);
  EXPECT_NE(err.find("more than 1000000 nodes"), std::string::npos) << err;
}

TEST(YamlKeys, AListOrMappingAsAKeyIsRefusedByPath) {
  // Found by tests/fuzz (geometry): loaders read keys as strings, and yaml-cpp threw converting these.
  EXPECT_EQ(dup("pen_geometry: {? [a, b]: 1}\n").rfind("pen_geometry.[a, b]: a key must be a plain name", 0), 0u)
      << dup("pen_geometry: {? [a, b]: 1}\n");
  EXPECT_NE(dup("? {x: 1}\n: 2\n").find("a key must be a plain name"), std::string::npos);
  EXPECT_EQ(dup("~: 1\n"), "");  // a null key is a scalar: left to the loaders (unknown key)
}
