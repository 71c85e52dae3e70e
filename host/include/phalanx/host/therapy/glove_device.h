#pragma once
/// glove5 as a therapy device: 5 channels (one per finger, pad force in N), 15 joints (finger flexion from the
/// 15 mechanism angles through the glove kinematics, 000 eq 3–8).
#include <array>

#include "phalanx/apps/glove5.h"
#include "phalanx/glove/kinematics.h"
#include "phalanx/host/therapy/device.h"

namespace phalanx::host::therapy {

class GloveTherapyDevice : public TherapyDevice {
 public:
  /// params: optional finger segment lengths p1..p3 (mm) by finger name; validated (5..120 mm each).
  static std::unique_ptr<GloveTherapyDevice> make(const KinematicParams& params, std::string& error);

  std::string name() const override { return "glove5"; }
  std::size_t channelCount() const override { return 5; }
  std::string channelName(std::size_t channel) const override;
  std::string effortUnit() const override { return "N"; }
  double effortLimit(std::size_t channel) const override;
  std::size_t jointCount() const override { return 15; }
  std::string jointName(std::size_t joint) const override;
  std::size_t jointChannel(std::size_t joint) const override { return joint / 3; }
  std::pair<double, double> jointBounds(std::size_t joint) const override;
  std::vector<std::string> sampleNames() const override;
  void observe(const TelemetryFrame& tel, Observation& out) override;
  float setpointFromEffort(std::size_t, double effort) const override { return static_cast<float>(effort); }
  double effortFromSetpoint(std::size_t, float setpoint) const override { return static_cast<double>(setpoint); }
  std::vector<std::pair<uint16_t, float>> startupParams() const override { return {{apps::glove5_param::kTare, 1.0f}}; }
  double startupSettleS() const override { return 0.1; }
  std::vector<uint16_t> startupReadback() const override { return {apps::glove5_param::kTare}; }
  std::string startupWarning(uint16_t id, float value) const override;
  std::unique_ptr<Controller> makeGraspController(const std::string& scene, std::string& error) const override;

  const phalanx::glove::Model<double>& model(std::size_t finger) const { return models_[finger]; }

 private:
  std::array<phalanx::glove::Model<double>, 5> models_{};
  std::array<phalanx::glove::Data<double>, 5> data_{};
};

}  // namespace phalanx::host::therapy
