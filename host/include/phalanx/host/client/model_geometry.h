#pragma once
/// The geometry the client channel's device models use (the daemon's --glove-geometry / --pen-geometry files, else
/// the compile-time defaults). Kept apart from device_model.h so that the daemon's own headers stay light.
#include <array>

#include "phalanx/glove/kinematics.h"
#include "phalanx/pen/kinematics.h"

namespace phalanx::host::client {

struct ModelGeometry {
  std::array<phalanx::glove::Model<double>, 5> glove = defaultGlove();
  phalanx::pen::Geometry<double> pen = phalanx::pen::defaultGeometry<double>();
  static std::array<phalanx::glove::Model<double>, 5> defaultGlove();
};

}  // namespace phalanx::host::client
