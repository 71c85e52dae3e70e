#pragma once
/// The ROS 2 standard message types the MCAP recordings use, as `ros2msg` schema text (the message definition
/// followed by each type it uses, the form rosbag2 writes into MCAP) and a CDR (XCDR1, little-endian, the ROS 2
/// wire format) writer for them. Kept apart from the DDS bridge's IDL on purpose: the integrator reconciles the
/// two (same type names, same fields).
#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace phalanx::host::record::ros2 {

/// Schema names (rosbag2 writes "pkg/msg/Type") and their ros2msg definitions.
inline constexpr const char* kJointStateName = "sensor_msgs/msg/JointState";
inline constexpr const char* kWrenchStampedName = "geometry_msgs/msg/WrenchStamped";
inline constexpr const char* kPoseStampedName = "geometry_msgs/msg/PoseStamped";
inline constexpr const char* kDiagnosticArrayName = "diagnostic_msgs/msg/DiagnosticArray";
const std::string& jointStateDefinition();
const std::string& wrenchStampedDefinition();
const std::string& poseStampedDefinition();
const std::string& diagnosticArrayDefinition();

struct Header {
  int32_t sec = 0;
  uint32_t nanosec = 0;
  std::string frame_id;
};
/// stamp from nanoseconds since the Unix epoch.
Header headerAt(uint64_t time_ns, std::string frame_id = {});

struct JointState {
  Header header;
  std::vector<std::string> name;
  std::vector<double> position, velocity, effort;
};
struct WrenchStamped {
  Header header;
  std::array<double, 3> force{}, torque{};
};
struct PoseStamped {
  Header header;
  std::array<double, 3> position{};
  std::array<double, 4> orientation{0.0, 0.0, 0.0, 1.0};  ///< quaternion x, y, z, w
};
struct DiagnosticStatus {
  uint8_t level = 0;  ///< 0 OK, 1 WARN, 2 ERROR, 3 STALE
  std::string name, message, hardware_id;
  std::vector<std::pair<std::string, std::string>> values;
};
struct DiagnosticArray {
  Header header;
  std::vector<DiagnosticStatus> status;
};

/// Serialised message: the 4-byte CDR encapsulation header (little-endian) then the body.
std::vector<uint8_t> encode(const JointState& m);
std::vector<uint8_t> encode(const WrenchStamped& m);
std::vector<uint8_t> encode(const PoseStamped& m);
std::vector<uint8_t> encode(const DiagnosticArray& m);

/// CDR writer (XCDR1, little-endian): each primitive aligned to its own size, counted from after the
/// encapsulation header; strings as u32 length (with the terminating NUL) + bytes + NUL; sequences as u32 count +
/// elements.
class CdrWriter {
 public:
  CdrWriter();
  void u8(uint8_t v) { buf_.push_back(v); }
  void i32(int32_t v) { put(static_cast<uint32_t>(v), 4); }
  void u32(uint32_t v) { put(v, 4); }
  void f64(double v);
  void str(const std::string& s);
  void header(const Header& h);
  void f64seq(const std::vector<double>& v);
  void vec3(const std::array<double, 3>& v) {
    for (double x : v) f64(x);
  }
  std::vector<uint8_t> take() { return std::move(buf_); }

 private:
  void align(std::size_t n);
  void put(uint64_t v, std::size_t n);
  std::vector<uint8_t> buf_;
};

}  // namespace phalanx::host::record::ros2
