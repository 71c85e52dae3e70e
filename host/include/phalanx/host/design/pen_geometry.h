#pragma once
/// Pen geometry file: the YAML `phalanx design pen-gii --yaml` writes and the pen controller consumes
/// (`phalanx run --pen-geometry`, config key `pen.geometry`; docs/design-tools.md §"Geometry files").
///
///   pen_geometry:
///     units: m
///     l6_reading: centre to universal joint (pen length 2 l6)
///     l1_m: 0.024     # shoulder spacing          l2_m: upper arm     l3_m: forearm
///     l4_m: 0.08      # waist-axis spacing        l6_m: pen centre → each universal joint
///     home_z_m: 0.20  # workspace centre / home depth along k
///     analysis: {...} # optional, informative (ignored by the loader)
#include <map>
#include <string>

#include "phalanx/pen/kinematics.h"

namespace phalanx::host::design {

/// YAML text of a pen geometry; `analysis` entries (e.g. GII, Q1, distance) are written under `analysis`.
std::string penGeometryYaml(const pen::Geometry<double>& g, const std::string& comment,
                            const std::map<std::string, double>& analysis = {});

/// Reads and validates a pen geometry file: every key known, every length a finite number > 0 (metres), and
/// the lengths must make a pen that reaches its home pose (pen::makeModel). Returns "" or an error that names
/// the file and the offending key. `out` is written only on success.
std::string loadPenGeometryYaml(const std::string& path, pen::Geometry<double>& out);

}  // namespace phalanx::host::design
