// phalanxd built without Cyclone DDS (cmake -DPHALANX_DDS=OFF, or cyclonedds-dev absent): the dds section is
// still parsed and validated, and enabling it is refused with this reason.
#include "phalanx/host/dds/dds_bridge.h"

namespace phalanx::host::dds {

bool bridgeAvailable() { return false; }

std::unique_ptr<Bridge> startBridge(const DdsOptions&, const BridgeDevice&, LoopPort&, std::string& error) {
  error = "dds: this phalanxd was built without Cyclone DDS (install cyclonedds-dev and rebuild; docs/dds.md)";
  return nullptr;
}

}  // namespace phalanx::host::dds
