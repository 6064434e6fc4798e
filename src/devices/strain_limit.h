// SPDX-License-Identifier: Apache-2.0
#pragma once

// The strain limit (docs/method.md, "Strain limit"): each frame's cloth edges brought back into
// a band around their rest lengths by Jacobi iterations of edge projections (Provot 1995's
// deformation constraints, solved the position-based way). StrainLimitBackend is the op every
// device implements: OpenCL in kernels/strain_limit.cl (src/devices/cl/cl_strain_limit.cpp), the
// host reference in src/devices/host/host_strain_limit.cpp; strainLimitTables() builds the
// tables both take.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/mesh.h>

#include "device_array.h"

namespace drivenshape {

/// The strain limit's tables: the mesh's edges as every vertex's list of incident edges
/// (compressed rows, in the order of meshEdges()), each entry with the edge's band and the
/// vertex's share of the edge's correction, and every vertex's step.
///
///   start     V + 1 offsets: vertex v's entries are start[v] .. start[v + 1] - 1
///   other     per entry: the edge's other vertex
///   lower     per entry: (1 - s) L, L the edge's rest length
///   upper     per entry: (1 + s) L
///   share     per entry: this vertex's share of the edge's correction, w_v / (w_v + w_other)
///             with w the vertices' weights (0: the vertex does not move)
///   step      per vertex: relaxation / n, n its entries with a share (0 when it has none)
///   omega     per iteration: the Chebyshev weight of that iteration (1: a plain Jacobi step)
///   compression  one gain for the corrections that lengthen an edge (below its band), 0 to 1
///
/// Each iteration, every vertex p takes, for each incident edge whose length l is outside
/// [lower, upper] (and not 0), the correction share * (l - t) / l * (q - p) towards (or away
/// from) its other end q, t the band's nearer end, times `compression` when the edge is too
/// short; it moves by step times their sum (none: it stays bitwise). n counts every edge that
/// can move the vertex, not only those outside the band now: a count that changed with the
/// positions would make the result jump where an edge crosses an end of its band (on a quad mesh
/// a vertex stretched one way moves by relaxation / 4 of its two corrections). Every vertex reads
/// the positions of the iteration before (Jacobi), so the result is the same in any order, on any
/// number of threads.
///
/// Chebyshev acceleration (Wang 2015, "A Chebyshev semi-iterative approach for accelerating
/// projective and positional dynamics"): iteration k takes the Jacobi result x^ of x_k and moves
/// on to x_{k+1} = omega_k (x^ - x_{k-1}) + x_{k-1}, so each step carries the momentum of the
/// last two. Jacobi alone shrinks a smooth stretch, the kind the binding and the blend leave on
/// the whole garment, by little per iteration (each vertex sees only its neighbours); the
/// acceleration brings the band within reach of 24 iterations. omega_k = 1 is the plain step
/// (x_{k+1} = x^, bitwise), as omega_0 must be: there is no x_{-1}. A vertex that no edge can
/// move (share 0 on every entry, step 0) takes no momentum, x_{k+1} = x^ = x_k: only its skin
/// plane moves it, onto the plane and no further.
struct StrainLimitTables {
  int vertexCount = 0;
  int iterations = 0;
  std::vector<std::int32_t> start;
  std::vector<std::int32_t> other;
  std::vector<float> lower;
  std::vector<float> upper;
  std::vector<float> share;
  std::vector<float> step;
  std::vector<float> omega;
  /// Pushing a short edge's ends apart along it turns any sideways offset of one end into more of
  /// it (the edge buckles); the acceleration amplifies that. A gain below 1 on those corrections
  /// keeps the iterations' answer from amplifying small differences of their input.
  float compression = 1.0f;
};

/// The Chebyshev weights of `iterations` iterations: 1 before iteration `from` (>= 1), then
/// omega_from = 2 / (2 - rho^2) and omega_k = 4 / (4 - rho^2 omega_{k-1}), rho the estimated
/// spectral radius of the plain iteration (0 <= rho < 1; 0 gives plain Jacobi). Throws
/// Error(kInternal) outside those ranges.
std::vector<float> chebyshevWeights(int iterations, double rho, int from);

/// The tables for `mesh` (its positions are the rest lengths): its edges (meshEdges(); those of
/// zero rest length are left out: they have no strain), the band [(1 - band) L, (1 + band) L],
/// `omega` (one Chebyshev weight per iteration, chebyshevWeights(); empty = plain Jacobi,
/// `iterations` ones), `weights` (V values >= 0, 0 = fixed; empty = every vertex 1) and
/// `compression` (StrainLimitTables::compression). Throws Error(kInternal) on a band outside
/// [0, 1), iterations < 0, a relaxation outside (0, 2), an omega of another length, weights of
/// another length or below 0, or a compression outside (0, 1].
StrainLimitTables strainLimitTables(const Mesh& mesh, double band, int iterations,
                                    double relaxation, std::vector<float> omega = {},
                                    const std::vector<float>& weights = {},
                                    double compression = 1.0);

/// Brings the edges of each frame into their band: `iterations` Jacobi iterations on each frame
/// alone (see StrainLimitTables), each keeping every vertex in front of its skin plane when
/// `planes` are given. Frame blocks are frame-major float32:
///
///   positions  F x 3V   vertex v of frame f, axis a at [f * 3V + 3v + a]
///   planes     F x 4V   vertex v's plane (m, c) at [f * 4V + 4v] (ClosestBackend::skinPlanes),
///                       or null: none
///
/// After each iteration, a vertex with a plane (m not 0) whose result x has m . x < c moves to
/// x + (c - m . x) m: in front of the plane, so that the limit cannot pull the cloth into the
/// body, where it would come out again stretched by the resolution after it. The planes are taken
/// once, before the iterations (a vertex slides along its plane). upload() once (again to replace
/// the tables), then limit() many times; limit() before upload() throws Error(kInternal). The
/// result of a frame does not depend on the other frames of the call, on the chunking or on the
/// threads. Not thread-safe.
///
///   stayed     F x V ints, or null: on return a vertex's mark is 0 unless it was non-zero and
///              the vertex ended less than `reach` from where it started. A caller that knew each
///              marked vertex at least C clear of the skin knows it at least C - reach clear now
///              (distance to a surface changes no faster than the point moves), which lets the
///              resolution after the limit keep the clearance certificate's answers.
class StrainLimitBackend {
 public:
  virtual ~StrainLimitBackend() = default;
  /// "host" or the OpenCL device name.
  virtual std::string name() const = 0;
  /// Checks the tables (Error(kInternal) when they do not agree) and keeps them.
  virtual void upload(const StrainLimitTables& tables) = 0;
  /// The iterations on `frameCount` frames of `positions`, in place (`planes` and `stayed` may
  /// be null; `reach` is read with `stayed`).
  virtual void limit(int frameCount, float* positions, const float* planes, std::int32_t* stayed,
                     float reach) = 0;
  /// The same on DeviceArrays (F x 3V floats, F x 4V floats, F x V ints; `planes` and `stayed`
  /// may be null): an OpenCL backend works on the arrays' device memory and copies nothing back;
  /// this default works on the host copies.
  virtual void limitBlock(int frameCount, DeviceArray& positions, DeviceArray* planes,
                          DeviceArray* stayed, float reach) {
    limit(frameCount, positions.modify<float>(),
          planes != nullptr ? planes->read<float>() : nullptr,
          stayed != nullptr ? stayed->modify<std::int32_t>() : nullptr, reach);
  }
  /// The planes' step alone, with no iteration and no tables (no upload() needed): every vertex
  /// of `frameCount` frames of `vertexCount` vertices in `positions` (F x 3V) behind its plane in
  /// `planes` (F x 4V) moves onto it, as after an iteration of limit(); the others stay bitwise.
  /// Throws Error(kInternal) for a negative count.
  virtual void keepInFront(int frameCount, int vertexCount, float* positions,
                           const float* planes) = 0;
  /// keepInFront() on DeviceArrays; this default works on the host copies.
  virtual void keepInFrontBlock(int frameCount, int vertexCount, DeviceArray& positions,
                                DeviceArray& planes) {
    keepInFront(frameCount, vertexCount, positions.modify<float>(), planes.read<float>());
  }
};

/// The host reference (plain C++, double arithmetic, frames in parallel on `threads` host
/// threads; 0 = one per hardware thread).
std::unique_ptr<StrainLimitBackend> makeHostStrainLimit(int threads = 0);

namespace strain_limit_checks {

/// Throws Error(kInternal) unless the tables agree with each other (see StrainLimitTables).
void checkTables(const StrainLimitTables& tables);
/// Throws Error(kInternal) for limit() before upload() or with a negative frame count.
void checkCall(bool uploaded, int frameCount);
/// Throws Error(kInternal) for keepInFront() with a negative frame or vertex count.
void checkInFront(int frameCount, int vertexCount);

}  // namespace strain_limit_checks

}  // namespace drivenshape
