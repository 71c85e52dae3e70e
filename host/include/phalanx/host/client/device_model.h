#pragma once
/// The client channel's device-model stage (docs/sdk.md §"Model level"): each cycle the telemetry through the
/// host's own device models into the model-level state a client reads (glove: finger angles, fingertip poses,
/// pad forces; SEA finger: joint flexion and finger torques; pen: pose, velocity, measured wrench), and a
/// client's model-level command (or its compliant fallback) into raw setpoints - BEFORE the limits stage, which
/// then applies to the converted command like to any other. The models are the host's: glove kinematics
/// (000 eq 3–8), SeaTherapyDevice (001 eq 3–5, 6/11, 9), pen forward kinematics and PenForceSplitter
/// (seeds/004 Fig. 18). Everything is preallocated: no allocation per cycle.
#include <array>
#include <cstdint>
#include <memory>

#include "phalanx/glove/kinematics.h"
#include "phalanx/host/client/model_geometry.h"
#include "phalanx/host/client/wire.h"
#include "phalanx/host/pen/force_split.h"
#include "phalanx/host/session.h"
#include "phalanx/pen/kinematics.h"
#include "phalanx/protocol/devices.h"

namespace phalanx::host::therapy {
class SeaTherapyDevice;
}

namespace phalanx::host::client {

/// The outcome of one conversion.
enum class ConvertStatus : uint8_t {
  kExact = 0,        ///< the command is what the model converted
  kSaturated = 1,    ///< the device model scaled it down (SEA exoskeleton torque, pen force split): counted
  kModelInvalid = 2, ///< no usable model this cycle (kinematics failed): zero setpoints
  kWrongDevice = 3,  ///< the command kind is not this device's: refused like an invalid command
};

class DeviceModelStage {
 public:
  DeviceModelStage(const protocol::DeviceLayout& layout, const ModelGeometry& geometry);
  ~DeviceModelStage();
  DeviceModelStage(const DeviceModelStage&) = delete;
  DeviceModelStage& operator=(const DeviceModelStage&) = delete;

  /// Once per cycle (a repeated frame - same device time - keeps the velocities).
  void observe(const TelemetryFrame& tel);
  /// Copy this device's model block into the state.
  void fill(client_wire::StatePayload& s) const;
  /// Model-level command → setpoints[0..setpoint_count); `scale` the fraction delivered.
  ConvertStatus convert(client_wire::CommandKind kind, const float* model, protocol::Command& cmd, float& scale);
  /// The fallback spring-damper at this cycle's state → setpoints (through the same conversion).
  ConvertStatus renderSpring(const client_wire::FallbackSpring& spring, protocol::Command& cmd, float& scale);
  /// Whether a command's model values (for its kind) are finite and its spring is finite with k, b ≥ 0.
  static bool finite(const client_wire::CommandPayload& c);

  /// The models' double-precision results of the last observe(), for other outputs of the same state (the DDS
  /// bridge, docs/dds.md, runs a stage of its own on its thread and publishes these).
  bool gloveValid(size_t finger) const { return glove_.valid[finger] != 0; }
  const phalanx::glove::Data<double>& gloveKinematics(size_t finger) const { return glove_data_[finger]; }
  bool penValid() const { return pen_.valid != 0; }
  /// The pen geometry made a model (else nothing of the pen is computed); penKinematics().q_rad holds the
  /// joint angles even when the forward kinematics is not usable.
  bool penModelOk() const { return pen_model_ok_; }
  const phalanx::pen::Data<double>& penKinematics() const { return pen_kin_; }
  /// The measured wrench at the pen centre; false when it is unknown this frame (no kinematics, or a
  /// pantograph's Jacobian singular).
  bool penWrench(host::pen::PenWrench& w) const {
    w = pen_wrench_;
    return pen_.valid != 0 && pen_wrench_ok_;
  }

 private:
  void observeGlove(const TelemetryFrame& tel, double dt);
  void observeSea(const TelemetryFrame& tel);
  void observePen(const TelemetryFrame& tel, double dt);
  double lowPass(double dt) const;

  const protocol::DeviceLayout& layout_;
  ModelGeometry geometry_;
  std::array<phalanx::glove::Data<double>, 5> glove_data_{};
  std::unique_ptr<therapy::SeaTherapyDevice> sea_;
  phalanx::pen::Model<double> pen_model_{};
  bool pen_model_ok_ = false;
  phalanx::pen::Data<double> pen_kin_{};
  host::pen::PenForceSplitter splitter_;
  host::pen::SplitResult split_{};
  client_wire::GloveModelState glove_{};
  client_wire::SeaModelState sea_state_{};
  client_wire::PenModelState pen_{};
  host::pen::PenWrench pen_wrench_{};
  bool pen_wrench_ok_ = false;
  std::array<double, 10> prev_{};     ///< previous positions for the velocity estimates
  bool have_prev_ = false;
  uint64_t last_device_time_us_ = 0;
};

}  // namespace phalanx::host::client
