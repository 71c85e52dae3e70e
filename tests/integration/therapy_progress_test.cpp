// Issue #25 items 5 and 6: a patient's progress over time and the FHIR export of the instrumented assessments.
// Session records come from the SEA finger in lockstep (the simulated spastic patient of the assessment tests,
// tests/support/sea_assessment_session.h): three sessions of one patient whose spasticity and strength improve,
// the second with a real fault (the host stops commanding for 100 ms: the firmware latches command-timeout and
// goes safe until the fault is cleared). A small cohort gives the repeatability file (ICC(2,1), MDC95). Then the
// real CLI (`phalanx record progress`, `record report`, `record fhir`):
//  - the progress PDF renders (Chromium's print, checked with pdftoppm: the planned page count, no blank page;
//    the PNGs are kept under build/host/progress-pages/), and its trend values equal each session report's figures;
//  - the faulted session's locked cycles are excluded (counted against the record itself);
//  - unknown patient, empty or missing directory, an unreadable or renamed record: clear errors;
//  - each session's FHIR bundle validates with fhir.resources (tools/fhir-validate.py) and holds every new figure
//    with the report's value and its ICC/MDC.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "../support/sea_assessment_session.h"
#include "phalanx/host/therapy/assessment_analysis.h"
#include "phalanx/host/therapy/fhir.h"
#include "phalanx/host/therapy/progress.h"
#include "phalanx/host/therapy/records_dir.h"
#include "process.h"

using phalanx::test::binPath;
using phalanx::test::Process;
namespace sa = phalanx::test::sea_assessment;
namespace fs = std::filesystem;

namespace {

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// The JSON a report or progress page embeds in <script type='application/json' id='ID'>.
nlohmann::json embedded(const std::string& html, const std::string& id) {
  const std::string open = "<script type='application/json' id='" + id + "'>";
  const auto a = html.find(open);
  if (a == std::string::npos) return nullptr;
  std::string j = html.substr(a + open.size(), html.find("</script>", a) - a - open.size());
  for (auto [from, to] : {std::pair<std::string, std::string>{"&quot;", "\""}, {"&#39;", "'"}, {"&lt;", "<"},
                          {"&gt;", ">"}, {"&amp;", "&"}}) {
    for (std::size_t p = 0; (p = j.find(from, p)) != std::string::npos; p += to.size()) j.replace(p, from.size(), to);
  }
  return nlohmann::json::parse(j, nullptr, false);
}

/// The CLI, waited for; rc set.
struct Cli {
  int rc = 0;
  std::string out, err;
};
Cli cli(const std::vector<std::string>& args) {
  std::vector<std::string> argv = {binPath("phalanx")};
  argv.insert(argv.end(), args.begin(), args.end());
  Process p(argv);
  Cli c;
  c.rc = p.wait(300000);
  c.out = p.stdoutText();
  c.err = p.stderrText();
  return c;
}

bool haveTool(const char* path) { return ::access(path, X_OK) == 0; }

/// Locked cycles counted from the record itself, by the rule docs/therapy.md states: a cycle with a latched
/// fault, or after one while the device still holds (safe/lock) and the session commands it to move.
std::size_t lockedCycles(const std::string& path, std::size_t& fault_cycles, double& first_fault_s, double& last_locked_s) {
  phalanx::host::record::SessionRecord rec;
  EXPECT_EQ(phalanx::host::record::readRecord(path, rec), "");
  auto holding = [](uint8_t m) {
    return m == static_cast<uint8_t>(phalanx::protocol::Mode::kSafe) || m == static_cast<uint8_t>(phalanx::protocol::Mode::kLock);
  };
  std::size_t locked = 0;
  fault_cycles = 0;
  first_fault_s = last_locked_s = -1.0;
  bool after = false;
  for (const auto& c : rec.cycles) {
    if (c.fault_bits != 0) {
      ++fault_cycles;
      if (first_fault_s < 0) first_fault_s = c.t_s;
      after = true;
    } else if (!holding(c.tel_mode)) {
      after = false;
    }
    if (c.fault_bits != 0 || (after && !holding(c.cmd_mode))) {
      ++locked;
      last_locked_s = c.t_s;
    }
  }
  return locked;
}

/// Fraction of non-white pixels of a binary PGM (P5, 8 bit) file.
double inkFraction(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::string magic;
  int w = 0, h = 0, max = 0;
  f >> magic >> w >> h >> max;
  f.get();
  if (magic != "P5" || w <= 0 || h <= 0 || max != 255) return -1.0;
  std::vector<unsigned char> px(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  f.read(reinterpret_cast<char*>(px.data()), static_cast<std::streamsize>(px.size()));
  std::size_t ink = 0;
  for (unsigned char c : px) ink += c < 200 ? 1 : 0;
  return static_cast<double>(ink) / static_cast<double>(px.size());
}

/// The Observation of a figure in a bundle (method.text ends with "figure <name>").
const nlohmann::json* observationOf(const nlohmann::json& bundle, const std::string& name) {
  const std::string tail = "figure " + name;
  for (const auto& e : bundle["entry"]) {
    const std::string m = e["resource"]["method"].value("text", std::string());
    if (m.size() >= tail.size() && m.compare(m.size() - tail.size(), tail.size(), tail) == 0) return &e["resource"];
  }
  return nullptr;
}

const nlohmann::json* componentOf(const nlohmann::json& obs, const std::string& code) {
  if (!obs.contains("component")) return nullptr;
  for (const auto& c : obs["component"]) {
    if (c["code"]["coding"][0]["code"] == code) return &c;
  }
  return nullptr;
}

}  // namespace

TEST(TherapyProgress, TrendsPdfAndFhirOfAPatientsSessions) {
  const bool ci = std::getenv("CI") != nullptr;
  if (!haveTool("/usr/bin/chromium") && !haveTool("/usr/bin/chromium-browser") && std::getenv("PHALANX_CHROMIUM") == nullptr) {
    if (ci) FAIL() << "chromium is not installed on CI (tools/setup.sh installs it)";
    GTEST_SKIP() << "chromium is not installed (Debian package 'chromium'; tools/setup.sh installs it)";
  }
  if (!haveTool("/usr/bin/pdftoppm")) {
    if (ci) FAIL() << "pdftoppm is not installed on CI (tools/setup.sh --test installs poppler-utils)";
    GTEST_SKIP() << "pdftoppm is not installed (Debian package 'poppler-utils'; tools/setup.sh --test installs it)";
  }
  char tmpl[] = "/tmp/phalanx-trends-XXXXXX";
  ASSERT_NE(::mkdtemp(tmpl), nullptr);
  const std::string dir = tmpl, records = dir + "/records", cohort = dir + "/cohort";
  fs::create_directories(records);
  fs::create_directories(cohort);

  // The repeatability study: 2 simulated patients × 2 sessions (noise and a donning offset of σ = 1°).
  std::vector<std::string> cohort_records;
  const std::vector<sa::Patient> cohort_patients = {{0.04, 55.0, 18.0, 0.10, 0.05, 0.9}, {0.06, 70.0, 26.0, 0.13, 0.065, 1.1}};
  for (std::size_t i = 0; i < cohort_patients.size(); ++i) {
    for (int k = 0; k < 2; ++k) {
      const std::string id = "cohort-" + std::to_string(i);
      const sa::SessionRun r = sa::runSession(cohort_patients[i], static_cast<uint32_t>(300 + 10 * i + k), sa::kDeg,
                                              cohort + "/" + id + "-2026110" + std::to_string(k + 1) + "T090000Z", id);
      cohort_records.push_back(r.record);
    }
  }
  const std::string rep_path = dir + "/repeatability.json";
  {
    const Cli c = cli([&] {
      std::vector<std::string> a = {"record", "repeatability"};
      a.insert(a.end(), cohort_records.begin(), cohort_records.end());
      a.insert(a.end(), {"--out", rep_path});
      return a;
    }());
    ASSERT_EQ(c.rc, 0) << c.err;
  }
  const nlohmann::json rep = nlohmann::json::parse(slurp(rep_path));

  // Three sessions of one patient, a week apart in their names, improving; the second one faulted.
  const std::string patient = "trend-01";
  const std::vector<sa::Patient> course = {{0.07, 55.0, 30.0, 0.09, 0.045, 1.0}, {0.05, 60.0, 24.0, 0.11, 0.055, 1.0},
                                           {0.03, 70.0, 18.0, 0.13, 0.065, 1.0}};
  const char* stamps[] = {"20261101T100000Z", "20261108T100000Z", "20261115T100000Z"};
  const double t_fault = sa::kPassiveS + sa::kTardieuS + 0.5;  // 0.5 s into the transparent rest
  bool cleared = false;
  auto fault = [&](double t, phalanx::host::LockstepRig& rig) {
    if (t >= t_fault && t < t_fault + 0.1) rig.setHostConnected(false);  // 100 ms: beyond the 20 ms command timeout
    else rig.setHostConnected(true);
    if (t >= t_fault + 0.8 && !cleared) {
      rig.session().sendClearFaults();
      cleared = true;
    }
  };
  std::vector<std::string> paths;
  for (std::size_t k = 0; k < course.size(); ++k) {
    const std::string stem = records + "/" + patient + "-" + stamps[k];
    const sa::SessionRun r = sa::runSession(course[k], static_cast<uint32_t>(500 + k), sa::kDeg, stem, patient,
                                            k == 1 ? sa::SessionHook(fault) : sa::SessionHook());
    paths.push_back(r.record);
  }
  // A record of another patient renamed into this directory (its header says cohort-0).
  fs::copy_file(cohort_records[0], records + "/other-02-20261101T100000Z.phrec");

  // The progress report: HTML, PDF, JSON.
  const std::string pdf = dir + "/progress.pdf";
  const Cli prog = cli({"record", "progress", "--patient", patient, "--records-dir", records, "--repeatability", rep_path,
                        "--pdf", pdf, "--json"});
  ASSERT_EQ(prog.rc, 0) << prog.err;
  const nlohmann::json p = nlohmann::json::parse(prog.out, nullptr, false);
  ASSERT_TRUE(p.is_object()) << prog.out.substr(0, 300);
  ASSERT_EQ(p["sessions"].size(), 3u);
  EXPECT_EQ(p["mdc_source"].get<std::string>(), rep["source"].get<std::string>() + ", " + rep_path);
  const std::string html = slurp(dir + "/progress.html");
  EXPECT_EQ(embedded(html, "progress"), p) << "the HTML embeds the same JSON";

  // Every trend value equals the session report's figure, and the locked time is the report's.
  std::size_t compared = 0;
  for (std::size_t k = 0; k < paths.size(); ++k) {
    const nlohmann::json& s = p["sessions"][k];
    EXPECT_EQ(s["file"], fs::path(paths[k]).filename().string()) << "oldest first";
    const std::string report = dir + "/report-" + std::to_string(k) + ".html";
    const Cli rc = cli({"record", "report", paths[k], "--out", report, "--repeatability", rep_path});
    ASSERT_EQ(rc.rc, 0) << rc.err;
    const nlohmann::json m = embedded(slurp(report), "metrics");
    ASSERT_TRUE(m.is_object());
    const auto figures = phalanx::host::therapy::progressFigures(m);
    EXPECT_EQ(s["figures"].size(), figures.size());
    for (const auto& [name, v] : figures) {
      bool found = false;
      for (const auto& f : p["figures"]) {
        if (f["name"] != name) continue;
        found = true;
        ASSERT_TRUE(f["values"][k].is_number()) << name << " session " << k;
        EXPECT_EQ(f["values"][k].get<double>(), v) << name << " session " << k;
        ++compared;
      }
      EXPECT_TRUE(found) << name;
    }
    EXPECT_EQ(s["excluded_cycles"], m["excluded_cycles"]);
    EXPECT_EQ(s["excluded_s"], m["excluded_s"]);
  }
  std::printf("trend values compared with the session reports: %zu\n", compared);
  EXPECT_GE(compared, 3u * 12u) << "Tardieu, passive ROM, MVF, active ROM and transparency figures in each session";
  // Figures with a repeatability entry carry its MDC95 and ICC.
  std::size_t with_mdc = 0;
  for (const auto& f : p["figures"]) {
    const std::string name = f["name"];
    if (!rep["figures"].contains(name)) {
      EXPECT_FALSE(f.contains("mdc95")) << name;
      continue;
    }
    EXPECT_EQ(f["mdc95"], rep["figures"][name]["mdc95"]) << name;
    EXPECT_EQ(f["icc"], rep["figures"][name]["icc"]) << name;
    ++with_mdc;
  }
  EXPECT_GE(with_mdc, 8u);
  // The improving course shows as such (the simulated truth went down for the gain, up for the strength).
  for (const auto& f : p["figures"]) {
    if (f["name"] == "max_force.mcp") {
      EXPECT_GT(f["values"][2].get<double>(), f["values"][0].get<double>());
    }
    if (f["name"] == "tardieu.catch_deg") {
      EXPECT_LT(f["values"][2].get<double>(), f["values"][0].get<double>());
    }
  }

  // The faulted session's locked period is excluded, counted against the record.
  for (std::size_t k = 0; k < paths.size(); ++k) {
    std::size_t fault_cycles = 0;
    double first = 0, last = 0;
    const std::size_t locked = lockedCycles(paths[k], fault_cycles, first, last);
    const nlohmann::json& s = p["sessions"][k];
    std::printf("session %zu: %zu cycles with a latched fault, %zu locked in all; progress excludes %zu (%.3f s), "
                "periods %s\n", k + 1, fault_cycles, locked, s["excluded_cycles"].get<std::size_t>(),
                s["excluded_s"].get<double>(), s["excluded_periods"].dump().c_str());
    EXPECT_EQ(s["excluded_cycles"].get<std::size_t>(), locked) << "session " << k + 1;
    if (k != 1) {
      EXPECT_EQ(locked, 0u) << "session " << k + 1 << " had no fault";
      continue;
    }
    EXPECT_GT(fault_cycles, 100u) << "the fault latched for the 0.7 s until it was cleared";
    ASSERT_EQ(s["excluded_periods"].size(), 1u);
    EXPECT_NE(s["excluded_periods"][0]["faults"].get<std::string>().find("command-timeout"), std::string::npos);
    EXPECT_DOUBLE_EQ(s["excluded_periods"][0]["start_s"].get<double>(), first);
    EXPECT_DOUBLE_EQ(s["excluded_periods"][0]["end_s"].get<double>(), last);
    EXPECT_NE(html.find("(" + std::to_string(locked) + " cycles)"), std::string::npos) << "shown in the sessions table";
  }

  // The PDF: the planned pages, none blank; PNGs kept as artefacts.
  ASSERT_EQ(slurp(pdf).substr(0, 5), "%PDF-");
  const std::string pages_dir = binPath("") + "/../progress-pages";
  fs::remove_all(pages_dir);
  fs::create_directories(pages_dir);
  {
    Process png({"/usr/bin/pdftoppm", "-r", "60", "-png", pdf, pages_dir + "/page"});
    ASSERT_EQ(png.wait(120000), 0) << png.stderrText();
    Process pgm({"/usr/bin/pdftoppm", "-r", "30", "-gray", pdf, dir + "/gray"});
    ASSERT_EQ(pgm.wait(120000), 0) << pgm.stderrText();
  }
  std::vector<std::string> pngs, grays;
  for (const auto& e : fs::directory_iterator(pages_dir)) pngs.push_back(e.path().string());
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().filename().string().rfind("gray", 0) == 0) grays.push_back(e.path().string());
  }
  std::sort(grays.begin(), grays.end());
  fs::copy_file(pdf, pages_dir + "/progress.pdf");
  std::printf("progress PDF: %zu pages (planned %d), PNGs in %s\n", pngs.size(), p["pages"].get<int>(), pages_dir.c_str());
  EXPECT_EQ(pngs.size(), p["pages"].get<std::size_t>());
  EXPECT_EQ(grays.size(), pngs.size());
  for (const std::string& g : grays) {
    const double ink = inkFraction(g);
    std::printf("  %s: %.2f %% ink\n", fs::path(g).filename().c_str(), 100.0 * ink);
    EXPECT_GT(ink, 0.005) << g << " is blank";
  }

  // Inputs refused with the reason.
  const Cli unknown = cli({"record", "progress", "--patient", "nobody", "--records-dir", records, "--pdf", dir + "/x.pdf"});
  EXPECT_EQ(unknown.rc, 1);
  EXPECT_NE(unknown.err.find("no session records of patient 'nobody' in " + records +
                             " (records there are of: other-02, trend-01)"), std::string::npos) << unknown.err;
  fs::create_directories(dir + "/empty");
  const Cli empty = cli({"record", "progress", "--patient", patient, "--records-dir", dir + "/empty", "--out", dir + "/x.html"});
  EXPECT_EQ(empty.rc, 1);
  EXPECT_NE(empty.err.find("it holds no session records"), std::string::npos) << empty.err;
  const Cli missing = cli({"record", "progress", "--patient", patient, "--records-dir", dir + "/none", "--out", dir + "/x.html"});
  EXPECT_EQ(missing.rc, 1);
  EXPECT_NE(missing.err.find("records directory " + dir + "/none: No such file or directory"), std::string::npos) << missing.err;
  const Cli renamed = cli({"record", "progress", "--patient", "other-02", "--records-dir", records, "--out", dir + "/x.html"});
  EXPECT_EQ(renamed.rc, 1);
  EXPECT_NE(renamed.err.find("header names patient 'cohort-0'"), std::string::npos) << renamed.err;
  std::ofstream(records + "/" + patient + "-20261122T100000Z.phrec") << "not a record at all";
  const Cli unreadable = cli({"record", "progress", "--patient", patient, "--records-dir", records, "--out", dir + "/x.html"});
  EXPECT_EQ(unreadable.rc, 1);
  EXPECT_NE(unreadable.err.find("cannot read the record " + records + "/" + patient + "-20261122T100000Z.phrec"),
            std::string::npos) << unreadable.err;
  const Cli bad_id = cli({"record", "progress", "--patient", "../etc", "--records-dir", records, "--out", dir + "/x.html"});
  EXPECT_EQ(bad_id.rc, 1);
  EXPECT_NE(bad_id.err.find("not a patient id"), std::string::npos) << bad_id.err;
  const Cli no_out = cli({"record", "progress", "--patient", patient, "--records-dir", records});
  EXPECT_EQ(no_out.rc, 2);
  EXPECT_FALSE(fs::exists(dir + "/x.html")) << "a refused report writes nothing";

  // FHIR: every session's bundle validates and carries each new figure with the report's value, ICC and MDC.
  for (std::size_t k = 0; k < paths.size(); ++k) {
    const std::string out = dir + "/session-" + std::to_string(k) + ".fhir.json";
    const Cli ex = cli({"record", "fhir", paths[k], "--out", out, "--repeatability", rep_path});
    ASSERT_EQ(ex.rc, 0) << ex.err;
    Process validate({"/usr/bin/env", "python3", std::string(PHALANX_SOURCE_DIR) + "/tools/fhir-validate.py", out});
    const int vrc = validate.wait(120000);
    if (vrc == 2 && !ci) GTEST_SKIP() << "fhir.resources is not installed (tools/setup.sh --test): " << validate.stderrText();
    std::printf("%s", validate.stdoutText().c_str());
    EXPECT_EQ(vrc, 0) << validate.stdoutText() << validate.stderrText();
    const nlohmann::json bundle = nlohmann::json::parse(slurp(out));
    if (k == 1) fs::copy_file(out, pages_dir + "/faulted-session.fhir.json");
    const nlohmann::json m = embedded(slurp(dir + "/report-" + std::to_string(k) + ".html"), "metrics");
    std::size_t checked = 0;
    for (const auto& [name, v] : phalanx::host::therapy::assessmentFigures(m)) {
      if (name.rfind("rom.", 0) == 0) continue;  // the active ROM has its own Observations (active-rom)
      const nlohmann::json* o = observationOf(bundle, name);
      ASSERT_NE(o, nullptr) << name << " missing from the bundle";
      EXPECT_EQ((*o)["subject"]["reference"], "Patient/" + patient);
      EXPECT_EQ((*o)["code"]["coding"][0]["system"], phalanx::host::therapy::kPhalanxCodeSystem);
      const double got = (*o)["valueQuantity"]["value"].get<double>();
      EXPECT_NEAR(got, v, 1e-5 * std::fabs(v)) << name << " (6 significant digits in the bundle)";
      if (rep["figures"].contains(name)) {
        const nlohmann::json* mdc = componentOf(*o, "mdc95");
        const nlohmann::json* icc = componentOf(*o, "icc-2-1");
        ASSERT_TRUE(mdc != nullptr && icc != nullptr) << name;
        const double want = rep["figures"][name]["mdc95"].get<double>();
        EXPECT_NEAR((*mdc)["valueQuantity"]["value"].get<double>(), want, 1e-5 * std::fabs(want)) << name;
        EXPECT_EQ((*mdc)["valueQuantity"]["code"], (*o)["valueQuantity"]["code"]) << name << ": MDC in the figure's unit";
      }
      if (k == 1) {
        EXPECT_TRUE(o->contains("note")) << name << ": the excluded locked time is noted";
      }
      ++checked;
    }
    std::printf("session %zu: %zu instrumented figures in the FHIR bundle, values equal to the report's\n", k + 1, checked);
    EXPECT_GE(checked, 8u) << "catch, threshold, gain, reflexes, passive ROM, MVF";
    for (const char* code : {"tardieu-catch-angle", "stretch-reflex-threshold-velocity", "stretch-reflex-gain",
                             "stretch-reflex-effort", "passive-rom-extension", "passive-rom-flexion", "max-voluntary-effort"}) {
      bool present = false;
      for (const auto& e : bundle["entry"]) present = present || e["resource"]["code"]["coding"][0]["code"] == code;
      EXPECT_TRUE(present) << code;
    }
  }
  fs::remove_all(dir);
}
