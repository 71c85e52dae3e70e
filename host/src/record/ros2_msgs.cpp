#include "phalanx/host/record/ros2_msgs.h"

#include <cstring>

namespace phalanx::host::record::ros2 {
namespace {

const std::string kSep = "================================================================================\n";
const std::string kHeaderDeps = kSep + "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n" + kSep +
                                "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";
const std::string kVector3 = kSep + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n";

}  // namespace

const std::string& jointStateDefinition() {
  static const std::string d =
      "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n" + kHeaderDeps;
  return d;
}
const std::string& wrenchStampedDefinition() {
  static const std::string d = "std_msgs/Header header\ngeometry_msgs/Wrench wrench\n" + kHeaderDeps + kSep +
                               "MSG: geometry_msgs/Wrench\ngeometry_msgs/Vector3 force\ngeometry_msgs/Vector3 torque\n" +
                               kVector3;
  return d;
}
const std::string& poseStampedDefinition() {
  static const std::string d = "std_msgs/Header header\ngeometry_msgs/Pose pose\n" + kHeaderDeps + kSep +
                               "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion "
                               "orientation\n" +
                               kSep + "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n" + kSep +
                               "MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n";
  return d;
}
const std::string& diagnosticArrayDefinition() {
  static const std::string d =
      "std_msgs/Header header\ndiagnostic_msgs/DiagnosticStatus[] status\n" + kHeaderDeps + kSep +
      "MSG: diagnostic_msgs/DiagnosticStatus\nbyte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\nbyte level\n"
      "string name\nstring message\nstring hardware_id\ndiagnostic_msgs/KeyValue[] values\n" +
      kSep + "MSG: diagnostic_msgs/KeyValue\nstring key\nstring value\n";
  return d;
}

Header headerAt(uint64_t time_ns, std::string frame_id) {
  Header h;
  h.sec = static_cast<int32_t>(time_ns / 1000000000u);
  h.nanosec = static_cast<uint32_t>(time_ns % 1000000000u);
  h.frame_id = std::move(frame_id);
  return h;
}

CdrWriter::CdrWriter() { buf_ = {0x00, 0x01, 0x00, 0x00}; }  // CDR_LE, no options

void CdrWriter::align(std::size_t n) {
  while ((buf_.size() - 4) % n != 0) buf_.push_back(0);
}

void CdrWriter::put(uint64_t v, std::size_t n) {
  align(n);
  for (std::size_t i = 0; i < n; ++i) buf_.push_back(static_cast<uint8_t>(v >> (8 * i)));
}

void CdrWriter::f64(double v) {
  uint64_t u;
  std::memcpy(&u, &v, 8);
  put(u, 8);
}

void CdrWriter::str(const std::string& s) {
  u32(static_cast<uint32_t>(s.size() + 1));
  buf_.insert(buf_.end(), s.begin(), s.end());
  buf_.push_back(0);
}

void CdrWriter::header(const Header& h) {
  i32(h.sec);
  u32(h.nanosec);
  str(h.frame_id);
}

void CdrWriter::f64seq(const std::vector<double>& v) {
  u32(static_cast<uint32_t>(v.size()));
  for (double x : v) f64(x);
}

std::vector<uint8_t> encode(const JointState& m) {
  CdrWriter w;
  w.header(m.header);
  w.u32(static_cast<uint32_t>(m.name.size()));
  for (const auto& n : m.name) w.str(n);
  w.f64seq(m.position);
  w.f64seq(m.velocity);
  w.f64seq(m.effort);
  return w.take();
}

std::vector<uint8_t> encode(const WrenchStamped& m) {
  CdrWriter w;
  w.header(m.header);
  w.vec3(m.force);
  w.vec3(m.torque);
  return w.take();
}

std::vector<uint8_t> encode(const PoseStamped& m) {
  CdrWriter w;
  w.header(m.header);
  w.vec3(m.position);
  for (double q : m.orientation) w.f64(q);
  return w.take();
}

std::vector<uint8_t> encode(const DiagnosticArray& m) {
  CdrWriter w;
  w.header(m.header);
  w.u32(static_cast<uint32_t>(m.status.size()));
  for (const auto& s : m.status) {
    w.u8(s.level);
    w.str(s.name);
    w.str(s.message);
    w.str(s.hardware_id);
    w.u32(static_cast<uint32_t>(s.values.size()));
    for (const auto& [k, v] : s.values) {
      w.str(k);
      w.str(v);
    }
  }
  return w.take();
}

}  // namespace phalanx::host::record::ros2
