#pragma once
/// One therapy session as the daemon runs it: patient profile, exercises, crash-safe record, report. Plugs
/// into runSession() through SessionHooks; the control API drives it from its own thread.
///
/// A therapy session never continues unrecorded: when its record cannot be written (records disk full, read-only,
/// failing), stopRequested() turns true at the writer's first error, runSession ends the session the normal way
/// (device commanded safe), and finish() reports the error (summary "error" and "session_record.error", exit code
/// record::kExitRecordFailed). docs/therapy.md, "When the records disk fails".
#include <atomic>
#include <ctime>
#include <memory>
#include <mutex>
#include <string>

#include <nlohmann/json.hpp>

#include "phalanx/host/daemon.h"
#include "phalanx/host/record/record_writer.h"
#include "phalanx/host/therapy/patient_guard.h"
#include "phalanx/host/therapy/profile.h"
#include "phalanx/host/therapy/session_plan.h"
#include "phalanx/host/therapy/therapy_controller.h"

namespace phalanx::host::therapy {

struct TherapySessionConfig {
  std::string record_path;      ///< "" = no record
  bool have_profile = false;
  Profile profile;
  /// "" = keep runSession's default controller (recording only); otherwise the first exercise.
  std::string exercise;
  nlohmann::json exercise_params;
  std::string report_path;      ///< "" = no report; written at session end from the record
  std::string previous_record;  ///< earlier session of the same patient, for the report's comparison
  std::string transparency_reference;  ///< "" or a device-free recording for the report's transparency r
  /// A session plan (validated by parsePlan); its step 0 must be `exercise`/`exercise_params`. The session ends
  /// when its last step ends.
  SessionPlan plan;
  /// Self-training (the profile's self_training): `profile.limits` already carry its effort scale.
  bool self_training = false;
  record::WriterConfig writer = compressedWriter();
  static record::WriterConfig compressedWriter() {
    record::WriterConfig w;
    w.cycle_blocks = true;  // format version 2 (docs/records.md, "Storage")
    return w;
  }
};

class TherapySession : public SessionHooks {
 public:
  explicit TherapySession(TherapySessionConfig config);
  ~TherapySession() override;

  // SessionHooks (session thread)
  std::unique_ptr<Controller> makeController(const protocol::DeviceLayout& layout, std::string& error) override;
  std::string onStart(const protocol::DeviceLayout& layout, const nlohmann::json& info) override;
  void onCycle(uint64_t wake_ns, double t_s, const TelemetryFrame& tel, const protocol::Command& cmd) override;
  void onDeviceEvent(const protocol::Event& event) override;
  PatientLimitStage* patientLimits() override { return loop_guard_; }
  /// The API's stop, or the record's writer failed (real time: two atomic loads).
  /// The API's stop, the record's writer failed, or the session plan's last step ended (real time: atomic loads).
  bool stopRequested() override {
    return stop_.load(std::memory_order_relaxed) || writer_.failed() || (plan_ && plan_->finished());
  }
  bool takeClearFaultsRequest() override { return clear_faults_.exchange(false, std::memory_order_relaxed); }
  void onEnd(const nlohmann::json& summary) override;

  /// Before runSession: create config().record_path now, so a records directory that cannot take it refuses the
  /// session before it starts (the header follows at onStart). "" or the error.
  std::string createRecord();
  /// The control API's record: a new <dir>/<patient>-<UTC second>[-n].phrec (records_dir.h), created now, with
  /// the report beside it (.html); sets config().record_path / report_path. "" or an error naming the directory.
  std::string createRecordIn(const std::string& dir, const std::string& patient, std::time_t when);
  /// The record's writer failed: the session stops (or has stopped) because of it.
  bool recordFailed() const { return writer_.failed(); }

  // API thread
  void requestStop() { stop_.store(true); }
  void requestClearFaults();
  /// Switch exercise: validated against the device and profile; "" or the reason it was refused.
  std::string setExercise(const std::string& name, const nlohmann::json& params);
  /// Pause / resume the exercise (and the plan's clock); "" or why not (no session, ended, already so).
  std::string pause();
  std::string resume();
  /// Tighten limits at run time (never above the profile's/device's): effort_max per channel name.
  std::string setLimits(const nlohmann::json& request);
  nlohmann::json limitsJson() const;
  /// Status: phase, exercise, device state, per-channel/joint values.
  nlohmann::json statusJson() const;
  /// Free retired exercises (call periodically off the loop).
  void housekeeping();
  /// Called by the owner after runSession returned (any outcome) with runSession's exit code: closes the record,
  /// writes the report and the end summary ("session_record": path, cycles_written, cycles_lost[, error]; "exit_code").
  /// Returns the session's exit code: runner_rc, or record::kExitRecordFailed when only the record failed.
  int finish(const nlohmann::json& summary, int runner_rc = 0);
  const TherapySessionConfig& config() const { return config_; }
  /// "starting" | "running" | "ended"
  std::string phase() const;
  nlohmann::json endSummary() const;

 private:
  TherapySessionConfig config_;
  record::RecordWriter writer_;
  std::shared_ptr<TherapyController> controller() const;
  mutable std::mutex ctl_mutex_;                 // guards ctl_ (API threads vs the session thread)
  std::shared_ptr<TherapyController> ctl_;       // shared with the Controller runSession runs
  TherapyController* loop_ctl_ = nullptr;        // the session thread's own pointer
  std::shared_ptr<PatientGuard> guard_;          // the patient's limits stage (guarded by ctl_mutex_)
  PatientGuard* loop_guard_ = nullptr;           // the session thread's own pointer
  std::shared_ptr<Pattern> pattern_;
  const protocol::DeviceLayout* layout_ = nullptr;
  std::unique_ptr<PlanRunner> plan_;  // built in makeController, before the loop runs
  Exercise* plan_handover_ = nullptr;  // session thread: a step's exercise not yet taken by the controller
  void runPlanCycle(double dt_s, const TelemetryFrame& tel, const protocol::Command& cmd);
  nlohmann::json planJson() const;
  std::atomic<bool> stop_{false};
  std::atomic<bool> clear_faults_{false};
  std::atomic<int> phase_{0};
  double last_t_s_ = 0.0;  // session thread only
  mutable std::mutex mutex_;  // guards end_summary_, finished_
  nlohmann::json end_summary_;
  bool finished_ = false;
  std::array<float, record::kMaxAux> aux_{};
};

}  // namespace phalanx::host::therapy
