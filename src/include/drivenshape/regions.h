// SPDX-License-Identifier: Apache-2.0
#pragma once

// Region-local weights (issue 4, step 4): the garment is split into regions (left leg, right
// leg), each region's weights are solved on its own driver rows only, and the blended shapes
// of the regions are mixed per vertex with a smooth partition of unity across the borders, so
// a shot whose left and right halves never occurred together in the reference still matches.

#include <string>
#include <vector>

#include <drivenshape/mesh.h>

namespace drivenshape {

/// One region: the driver vertices whose rows its QP sees and the driven vertices it owns.
struct Region {
  std::string name;
  std::vector<int> driverVertices;  ///< sorted
  std::vector<int> drivenVertices;  ///< sorted
};

/// Regions of a bake with their per-vertex mixing weights.
///
///   regions      R named regions, then (if some driver or driven vertex is in no region) one
///                implicit region "rest" whose QP sees every driver row and which owns the
///                uncovered vertices
///   drivenMix    R x Vd  weight of region r at driven vertex v at [r * Vd + v]
///   driverMix    R x Vp  the same on the driver (used to mix the blended driver P~)
///
/// For every vertex the weights are in [0, 1] and sum to 1 (a partition of unity).
struct RegionSet {
  std::vector<Region> regions;
  int falloff = 2;  ///< edge rings on each side of a border over which the weights ramp
  std::vector<float> drivenMix;
  std::vector<float> driverMix;
  int count() const { return static_cast<int>(regions.size()); }
};

/// Reads a region file (JSON):
///
///   {
///     "version": 1,                            (optional; 1 is the only version)
///     "falloff": 2,                            (optional; edge rings, default 2, 0 = hard)
///     "regions": [
///       {"name": "left", "driver": ["left_leg"], "driven": ["left_leg"]},
///       {"name": "right", "driver": {"groups": ["right_leg"], "vertices": [0, "10-99"]},
///        "driven": {"vertices": ["2300-4580"]}}
///     ]
///   }
///
/// "driver" and "driven" name vertices of the driver and driven meshes: a group name, a list
/// of group names, or an object with "groups" and/or "vertices" (0-based indices; a string
/// "a-b" is the inclusive range). A group stands for the vertices of its faces. Keys
/// "comment" are ignored anywhere; other keys are errors. A vertex may belong to one region
/// only. Throws Error(kInput) naming the file and the entry ("regions[1].driven") for a file
/// that cannot be read, malformed JSON, an unknown key or group (listing the known groups), an
/// index out of range, a region that names no vertex, a vertex named by two regions, or no
/// regions at all.
RegionSet readRegions(const std::string& path, const Mesh& driver, const Mesh& driven);

/// The same from JSON text; `source` names the text in messages.
RegionSet parseRegions(const std::string& jsonText, const std::string& source, const Mesh& driver,
                       const Mesh& driven);

/// Partition-of-unity weights of disjoint vertex sets on `mesh` (R x V, set-major). With s_r(v)
/// the signed edge-ring distance to the border of set r (+d - 1/2 inside, at d rings from the
/// nearest vertex outside; -(d - 1/2) outside, d rings from the nearest vertex inside), the raw
/// weight is smoothstep((s_r + F) / 2F) (a step at the border when F = 0) and the weights are
/// normalised to sum 1. For two complementary sets the raw weights already sum to 1 and each
/// is a monotone function of the distance to the border. Every vertex must be in some set.
std::vector<float> regionFalloff(const Mesh& mesh, const std::vector<std::vector<int>>& sets,
                                 int falloff);

}  // namespace drivenshape
