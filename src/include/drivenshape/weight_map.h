// SPDX-License-Identifier: Apache-2.0
#pragma once

// Weight maps: one number in [0, 1] per driven vertex, read from JSON, a one-channel EXR or the
// driven OBJ's face groups. The layers (drivenshape/layers.h) mix and scale by them.

#include <string>
#include <vector>

#include <drivenshape/mesh.h>

namespace drivenshape {

/// Reads a weight map for `driven` (Vd vertices) from `spec`, one of:
///
///   NAME.json           a JSON array of Vd numbers, [0.0, 1, 0.25, ...], or an object
///                       {"weights": [...]} (other keys: "comment" only)
///   NAME.exr            a one-channel point-cache EXR: channel W (or the file's only channel
///                       besides A) in the point-cache pixel layout, vertex v at pixel
///                       (v mod width, v div width), with dsVertexCount = Vd (writeWeightMapExr)
///   group:NAME[,NAME]   the `g`/`o` face groups of the driven OBJ: weight 1 on every vertex of
///                       their faces, 0 elsewhere (soften the edge with a falloff)
///
/// `what` names the map in messages ("--mix-weight"). Throws Error(kInput) naming the file and
/// the index for a wrong length, a value outside [0, 1], NaN or a non-number, and for an
/// unknown group (listing the known ones); Error(kUsage) for a spec of no known form.
std::vector<float> readWeightMap(const std::string& spec, const Mesh& driven,
                                 const std::string& what = "weight map");

/// Writes a weight map as a one-channel point-cache EXR (channel W, coverage A, dsVertexCount),
/// atomically, `width` pixels per row. Throws Error(kInput) for values outside [0, 1].
void writeWeightMapExr(const std::string& path, const std::vector<float>& weights,
                       int width = 1024);

/// The map softened across `rings` edge rings of `mesh`: each vertex gets the average of the
/// values within `rings` edges of it, weighted by (rings + 1 - edge distance), computed in
/// double. A vertex whose neighbourhood holds one value keeps it bitwise, so values more than
/// `rings` rings from any change are exact (weight 1 stays exactly 1). Across a straight
/// boundary of a regular mesh the result is monotone (a convolution of a step with a positive
/// kernel). rings = 0 returns the map unchanged. Throws Error(kUsage) for rings outside 0..64.
std::vector<float> smoothWeightMap(const std::vector<float>& weights, const Mesh& mesh, int rings);

}  // namespace drivenshape
