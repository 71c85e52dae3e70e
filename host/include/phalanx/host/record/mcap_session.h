#pragma once
/// A Phalanx session as MCAP channels (docs/records.md, "MCAP"): the encoder both `--record FILE.mcap` (live,
/// on the recorder's writer thread) and `phalanx record export FILE --mcap` (from a .phrec) use, so the two files
/// have the same topics and schemas.
///
/// Topics (SI units; ROS 2 types in ros2msg + CDR, the rest JSON with a JSON Schema naming every field):
///   /phalanx/joint_states            sensor_msgs/JointState: joint flexion (rad, flexion positive) per joint
///   /phalanx/mechanism/joint_states  sensor_msgs/JointState: the device's measured angles (rad) as sent
///   /phalanx/effort/<channel>        geometry_msgs/WrenchStamped: measured interaction effort of a channel
///                                    (fingertip pad force in N on force.z, or joint torque in N·m on torque.z)
///   /phalanx/telemetry               every telemetry sample by name (+ device time, seq, mode, fault bits)
///   /phalanx/command                 the command sent (mode, seq, setpoints by name)
///   /phalanx/therapy                 the therapy controller's values by name (session records)
///   /phalanx/limits                  limited-channel bits and e-stop / state flags, at every change
///   /phalanx/faults                  fault bits and their names, at every change
///   /phalanx/events                  session events (the .phrec's event records)
///   /phalanx/loop_stats, /diagnostics  loop statistics once per second (JSON; diagnostic_msgs/DiagnosticArray)
///   /phalanx/pen/pose, /phalanx/pen/wrench  pantograph: geometry_msgs/PoseStamped (pen centre and orientation)
///                                    and geometry_msgs/WrenchStamped (measured wrench at the centre), base frame
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/record/mcap_writer.h"
#include "phalanx/host/record/record_format.h"
#include "phalanx/host/record/record_reader.h"
#include "phalanx/protocol/devices.h"
#include "phalanx/pen/kinematics.h"

namespace phalanx::host::therapy {
class TherapyDevice;
}

namespace phalanx::host::record {

struct McapLayout {
  std::string device;                       ///< "glove5", …
  std::vector<std::string> samples, setpoints, aux;  ///< column names (with their units)
  uint64_t start_epoch_ns = 0;              ///< log time of t_s = 0 (wall clock, ns since the Unix epoch)
  nlohmann::json header;                    ///< stored as metadata "phalanx_session" (the .phrec header)
  /// A live `--record` file: the telemetry and command messages carry what a replay needs besides the samples
  /// (cmd_seq_echo, state_flags; the command's source and gain scales: addCycle's CommandExtras); the header then
  /// holds "replay" (record/replay.h).
  bool live = false;
  /// pantograph: the pen channels, computed with this model (the session's geometry).
  bool pen = false;
  phalanx::pen::Model<double> pen_model{};
};

/// What a live recording adds to each cycle's command (docs/records.md, "Replay").
struct CommandExtras {
  uint8_t source = 0;  ///< 0 the controller, 1 a Modbus client, 2 a client-channel client, 3 the e-stop (safe)
  std::array<uint16_t, protocol::kMaxSetpoints> gain_permille{};
};

class McapSession {
 public:
  /// device: the therapy adapter (joint flexion, efforts); null for a device without one (only the raw channels).
  McapSession(McapLayout layout, std::unique_ptr<therapy::TherapyDevice> device,
              McapWriter::Compression compression = McapWriter::Compression::kZstd);
  ~McapSession();
  /// The file's first bytes: magic, header, metadata, schemas and channels.
  std::vector<uint8_t> start();
  /// Log time of t_s = 0 (before the first addCycle; else McapLayout::start_epoch_ns).
  void setStartEpoch(uint64_t epoch_ns) { layout_.start_epoch_ns = epoch_ns; }
  /// Not real time (writer thread): one cycle → its messages in the open chunk.
  void addCycle(const CycleRecord& c, const CommandExtras* extras = nullptr);
  /// An event {"t_s", "kind", …}.
  void addEvent(const nlohmann::json& event);
  std::size_t chunkMessages() const { return writer_.chunkMessages(); }
  std::vector<uint8_t> takeChunk(uint64_t file_offset) { return writer_.takeChunk(file_offset); }
  /// Data End … magic (after the last takeChunk(); a last partial second of loop statistics is not written).
  std::vector<uint8_t> finish(uint64_t file_offset, uint32_t data_crc);
  uint64_t messageCount() const { return writer_.messageCount(); }

 private:
  uint64_t logTime(double t_s) const;
  void emitLoopStats(double t_s);
  void addPen(uint64_t t, const CycleRecord& c);
  std::string numbersJson(const std::vector<std::string>& names, const float* values, std::size_t n) const;

  McapLayout layout_;
  std::unique_ptr<therapy::TherapyDevice> device_;
  McapWriter writer_;
  uint16_t ch_joints_ = 0, ch_mechanism_ = 0, ch_telemetry_ = 0, ch_command_ = 0, ch_therapy_ = 0, ch_limits_ = 0,
           ch_faults_ = 0, ch_events_ = 0, ch_loop_ = 0, ch_diag_ = 0,
           ch_pen_pose_ = 0, ch_pen_wrench_ = 0;
  std::vector<uint16_t> ch_effort_;
  std::vector<std::size_t> angle_samples_;  // indices of the angle samples (mechanism joint states)
  int limited_aux_ = -1;
  bool have_device_ = false;
  bool first_ = true;
  uint16_t last_faults_ = 0, last_limited_ = 0;
  uint8_t last_flags_ = 0;
  // Loop statistics of the current second.
  double window_start_s_ = 0.0;
  uint64_t window_cycles_ = 0, last_host_ns_ = 0, window_missed_ = 0;
  double period_sum_s_ = 0.0, period_max_s_ = 0.0;
  uint16_t last_seq_ = 0;
};

/// Writes rec as MCAP (the same channels as a live recording) to path, through a temporary file renamed into
/// place when complete (as exportCsv; refused when path is the record's own file). "" or an error.
std::string exportMcap(const SessionRecord& rec, const std::string& path);

/// Names of a layout's samples / setpoints with their units, for CSV and MCAP headers: the therapy adapter's names
/// where the device has one, else "<kind><i>_<unit>" from the layout.
std::vector<std::string> sampleColumnNames(const protocol::DeviceLayout& layout);
std::vector<std::string> setpointColumnNames(const protocol::DeviceLayout& layout);

}  // namespace phalanx::host::record
