#include "phalanx/host/therapy/device.h"

#include "phalanx/host/therapy/glove_device.h"
#include "phalanx/host/therapy/sea_device.h"

namespace phalanx::host::therapy {

std::vector<std::string> TherapyDevice::setpointNames() const {
  std::vector<std::string> v;
  for (std::size_t c = 0; c < channelCount(); ++c) v.push_back("setpoint_" + channelName(c));
  return v;
}

int TherapyDevice::channelIndex(const std::string& n) const {
  for (std::size_t c = 0; c < channelCount(); ++c) {
    if (channelName(c) == n) return static_cast<int>(c);
  }
  return -1;
}

int TherapyDevice::jointIndex(const std::string& n) const {
  for (std::size_t j = 0; j < jointCount(); ++j) {
    if (jointName(j) == n) return static_cast<int>(j);
  }
  return -1;
}

std::unique_ptr<TherapyDevice> makeTherapyDevice(const std::string& device_name, const KinematicParams& params,
                                                 std::string& error) {
  if (device_name == "glove5") return GloveTherapyDevice::make(params, error);
  if (device_name == "sea_finger") return SeaTherapyDevice::make(params, error);
  error = "device '" + device_name + "' has no therapy adapter yet (supported: glove5, sea_finger)";
  return nullptr;
}

std::unique_ptr<TherapyDevice> makeTherapyDevice(const protocol::DeviceLayout& layout, const KinematicParams& params,
                                                 std::string& error) {
  return makeTherapyDevice(std::string(layout.name), params, error);
}

}  // namespace phalanx::host::therapy
