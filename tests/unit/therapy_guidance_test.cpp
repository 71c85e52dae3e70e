// The therapist-facing wording (issue #25 item 1): one fault-guidance table for the CLI, the dashboard and the
// report; anatomical order; numbers without float noise; the FHIR bundle's structure (the schema check is the
// fhir.resources validation in tests/integration/therapist_flow_test.cpp).
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "phalanx/host/session.h"
#include "phalanx/host/therapy/fhir.h"
#include "phalanx/host/therapy/guidance.h"
#include "phalanx/protocol/messages.h"

namespace th = phalanx::host::therapy;
namespace pf = phalanx::protocol::fault;

TEST(FaultGuidance, EveryFaultTheFirmwareCanLatchHasPlainWords) {
  std::set<std::string> names;
  for (uint16_t bit : {pf::kCommandTimeout, pf::kInvalidCommand, pf::kEstop, pf::kSensorRange, pf::kSensorStuck,
                       pf::kForceLimit, pf::kJointLimit, pf::kCurrentLimit, pf::kSensorSaturated, pf::kMotorAngle,
                       pf::kTickOverrun, pf::kInternal}) {
    const auto g = th::faultGuidance(bit);
    ASSERT_EQ(g.size(), 1u);
    EXPECT_EQ(std::string(g[0].fault), phalanx::host::faultName(bit)) << "the wire name, as status shows it";
    EXPECT_GT(std::string(g[0].what).size(), 20u);
    EXPECT_NE(std::string(g[0].safe).find("motors off"), std::string::npos);
    EXPECT_GT(std::string(g[0].action).size(), 20u);
    names.insert(g[0].fault);
  }
  EXPECT_EQ(names.size(), 12u) << "one row per fault";
  EXPECT_EQ(th::faultGuidanceTable().size(), 12u);
  // Several faults: one row each, in bit order; an unknown bit still gets words.
  const auto two = th::faultGuidanceJson(pf::kEstop | pf::kCommandTimeout);
  ASSERT_EQ(two.size(), 2u);
  EXPECT_EQ(two[0]["fault"], "command-timeout");
  EXPECT_EQ(two[1]["fault"], "estop");
  EXPECT_EQ(th::faultGuidance(1u << 12).size(), 1u);
  EXPECT_TRUE(th::faultGuidanceJson(0).empty());
  const std::string text = th::faultGuidanceText(pf::kForceLimit);
  EXPECT_NE(text.find("what happened:"), std::string::npos);
  EXPECT_NE(text.find("patient safe:"), std::string::npos);
  EXPECT_NE(text.find("what to do:"), std::string::npos);
}

TEST(AnatomicalOrder, FingersThumbToLittleJointsProximalToDistal) {
  const std::vector<std::string> alphabetical = {"index_dip", "index_mcp", "index_pip", "little_mcp", "middle_dip",
                                                 "ring_pip", "thumb_cmc", "thumb_ip", "thumb_mcp"};
  EXPECT_EQ(th::anatomicalOrder(alphabetical),
            (std::vector<std::string>{"thumb_cmc", "thumb_mcp", "thumb_ip", "index_mcp", "index_pip", "index_dip",
                                      "middle_dip", "ring_pip", "little_mcp"}));
  EXPECT_EQ(th::anatomicalOrder({"index", "little", "middle", "ring", "thumb"}),
            (std::vector<std::string>{"thumb", "index", "middle", "ring", "little"}));
  EXPECT_EQ(th::anatomicalOrder({"dip", "mcp", "pip"}), (std::vector<std::string>{"mcp", "pip", "dip"}));
  const nlohmann::json obj = {{"ring", 1}, {"thumb", 2}, {"index", 3}};
  EXPECT_EQ(th::anatomicalKeys(obj), (std::vector<std::string>{"thumb", "index", "ring"}));
}

TEST(HumanNumber, NoFloatNoiseAndNoNegativeZero) {
  EXPECT_EQ(th::humanNumber(-29.999999999999996), "-30");
  EXPECT_EQ(th::humanNumber(-0.0), "0");
  EXPECT_EQ(th::humanNumber(-0.0004, 3), "0");
  EXPECT_EQ(th::humanNumber(2.5), "2.5");
  EXPECT_EQ(th::humanNumber(0.3, 3), "0.3");
  EXPECT_EQ(th::humanNumber(70.0), "70");
  EXPECT_EQ(th::humanNumber(1.234567, 2), "1.23");
}

TEST(FhirBundle, ObservationsOfTheSessionsPatientWithCodesAndUnits) {
  const nlohmann::json m = {{"patient", "demo-001"}, {"device", "glove5"}, {"effort_unit", "N"},
                            {"start_utc", "2026-12-02T00:40:00Z"}, {"duration_s", 12.4}, {"complete", true},
                            {"rom_source", "assessment"}, {"excluded_s", 1.5}, {"faults_seen", "command-timeout"},
                            {"rom_deg", {{"index_pip", {5.0, 80.0}}, {"index_mcp", {0.0, 60.0}}}},
                            {"transparency", {{"index", {{"interaction_rms", 0.05}, {"interaction_peak", 0.2}}}}},
                            {"tracking", nlohmann::json::object()},
                            {"effort", {{"index", {{"peak_measured", 0.3}, {"peak_command", 0.0}}}}}};
  std::string err;
  const nlohmann::json b = th::fhirBundle(m, "demo-001-20261202T004000Z.phrec", err);
  ASSERT_EQ(err, "");
  EXPECT_EQ(b["resourceType"], "Bundle");
  EXPECT_EQ(b["type"], "collection");
  ASSERT_EQ(b["entry"].size(), 2u + 1u + 1u + 1u) << "2 ROM, 1 interaction, 1 peak effort, 1 session";
  const auto& rom = b["entry"][0]["resource"];
  EXPECT_EQ(rom["subject"]["reference"], "Patient/demo-001");
  EXPECT_EQ(rom["bodySite"]["text"], "index finger MCP joint") << "anatomical order: MCP first";
  EXPECT_EQ(rom["valueQuantity"]["value"], 60.0);
  EXPECT_EQ(rom["valueQuantity"]["system"], "http://unitsofmeasure.org");
  EXPECT_EQ(rom["code"]["coding"][0]["system"], th::kPhalanxCodeSystem);
  EXPECT_EQ(rom["effectivePeriod"]["end"], "2026-12-02T00:40:13Z");
  EXPECT_NE(rom["note"][0]["text"].get<std::string>().find("1.5 s"), std::string::npos) << "excluded time said";
  std::set<std::string> urls;
  for (const auto& e : b["entry"]) urls.insert(e["fullUrl"].get<std::string>());
  EXPECT_EQ(urls.size(), b["entry"].size()) << "distinct entry ids";
  // The same input gives the same bundle (deterministic ids).
  EXPECT_EQ(th::fhirBundle(m, "demo-001-20261202T004000Z.phrec", err), b);
  // A profile id that is no FHIR id ('_') is referred to by its identifier only; no patient: refused.
  nlohmann::json m2 = m;
  m2["patient"] = "p_1";
  const nlohmann::json b2 = th::fhirBundle(m2, "x.phrec", err);
  EXPECT_FALSE(b2["entry"][0]["resource"]["subject"].contains("reference"));
  EXPECT_EQ(b2["entry"][0]["resource"]["subject"]["identifier"]["value"], "p_1");
  m2["patient"] = "";
  EXPECT_TRUE(th::fhirBundle(m2, "x.phrec", err).is_null());
  EXPECT_NE(err.find("no patient"), std::string::npos);
}
