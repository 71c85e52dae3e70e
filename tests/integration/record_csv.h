#pragma once
// The --record CSV (docs/records.md) as columns by name, for the integration tests. Besides the named columns
// (force_index_N, setpoint_torque0_Nm, ...), each telemetry sample is also under `sample<i>` and each setpoint
// under `setpoint<i>`, by position: the samples follow `fault_bits`, the setpoints are the columns whose name
// starts with "setpoint".
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace phalanx::test {

struct RecordCsv {
  std::map<std::string, std::vector<double>> col;
  size_t rows() const { return col.count("t_s") != 0 ? col.at("t_s").size() : 0; }
  double at(const std::string& c, size_t i) const { return col.at(c)[i]; }
  /// The row whose t_s is nearest t (the summary's times are the same wake times as the CSV's).
  size_t rowAt(double t) const {
    const std::vector<double>& ts = col.at("t_s");
    size_t best = 0;
    for (size_t i = 0; i < ts.size(); ++i) {
      if (std::fabs(ts[i] - t) < std::fabs(ts[best] - t)) best = i;
    }
    return best;
  }
};

inline RecordCsv readRecordCsv(const std::string& path) {
  RecordCsv csv;
  std::ifstream f(path);
  std::string line, cell;
  std::getline(f, line);
  std::vector<std::string> names;
  std::stringstream hs(line);
  while (std::getline(hs, cell, ',')) names.push_back(cell);
  std::vector<std::string> alias(names.size());
  bool after_faults = false;
  int samples = 0, setpoints = 0;
  for (size_t i = 0; i < names.size(); ++i) {
    if (names[i].rfind("setpoint", 0) == 0) {
      alias[i] = "setpoint" + std::to_string(setpoints++);
    } else if (after_faults) {
      alias[i] = "sample" + std::to_string(samples++);
    }
    if (names[i] == "fault_bits") after_faults = true;
  }
  while (std::getline(f, line)) {
    std::stringstream rs(line);
    for (size_t i = 0; std::getline(rs, cell, ',') && i < names.size(); ++i) {
      const double v = std::stod(cell);
      csv.col[names[i]].push_back(v);
      if (!alias[i].empty() && alias[i] != names[i]) csv.col[alias[i]].push_back(v);
    }
  }
  return csv;
}

/// firmware-sim's --truth CSV (phalanxd --sim-truth; docs/sdk.md "Plant truth"): the plant's ground truth per device
/// tick, found by the device clock that the tick's telemetry carries (the --record CSV's device_time_us).
struct TruthCsv {
  RecordCsv csv;
  std::map<long long, size_t> row_of_time;
  size_t rows() const { return row_of_time.size(); }
  double at(const std::string& c, size_t i) const { return csv.at(c, i); }
  /// The truth row for a telemetry row's device time; false when the plant wrote none for it.
  bool find(double device_time_us, size_t& row) const {
    const auto it = row_of_time.find(std::llround(device_time_us));
    if (it == row_of_time.end()) return false;
    row = it->second;
    return true;
  }
};

inline TruthCsv readTruthCsv(const std::string& path) {
  TruthCsv t;
  t.csv = readRecordCsv(path);
  const auto c = t.csv.col.find("device_time_us");
  if (c == t.csv.col.end()) return t;
  for (size_t i = 0; i < c->second.size(); ++i) t.row_of_time[std::llround(c->second[i])] = i;
  return t;
}

}  // namespace phalanx::test
