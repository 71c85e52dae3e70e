#pragma once
/// Shared by the Cyclone DDS users of the host (the bridge, host/dds/cyclone_bridge.cpp; phalanx-teleop,
/// host/apps/teleop.cpp): needs Cyclone's headers, so it is not part of the public dds_bridge.h.
#include <cstdint>
#include <string>

#include <dds/dds.h>

namespace phalanx::host::dds {

/// A domain on one interface (name or IPv4 address), when one is given; else nothing (Cyclone's default choice
/// at the participant's creation). An error names the interface and Cyclone's reason.
std::string createDomain(uint32_t domain_id, const std::string& interface, dds_entity_t& domain);

}  // namespace phalanx::host::dds
