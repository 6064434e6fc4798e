// SPDX-License-Identifier: Apache-2.0
#pragma once

// The OpenCL backend of the correction stage (private to the devices room): the class
// ClClosest, whose members are defined one file per kernel stem. The host candidate search
// (shared with the host backend) and kernels/closest.cl for the exact choice from candidate
// lists, with the backend's glue (program build, setSurface, the array helpers), are in
// cl_closest.cpp; the BVH refit and walk (kernels/bvh.cl) in cl_bvh.cpp; the local-frame
// transfer and rebuild (kernels/transfer.cl) in cl_transfer.cpp; the clearance certificate
// (kernels/certificate.cl) in cl_certificate.cpp; the penetration resolution and the inside
// count (kernels/resolve.cl) in cl_resolve.cpp. One program holds all the kernels; it is built
// once per backend.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <CL/opencl.hpp>

#include <drivenshape/binding.h>
#include <drivenshape/mesh.h>

#include "closest.h"

#include <correction_types.h>
#include <shared_types.h>

#include "bvh.h"
#include "candidates.h"
#include "cl_program.h"
#include "device_array.h"

namespace drivenshape {

class ClClosest final : public ClosestBackend {
 public:
  ClClosest(const cl_util::ClTarget& target, const ClosestOptions& options);

  std::string name() const override { return mName; }

  void setSurface(const Mesh& driver, const BindingMask& mask) override;

  void setExitFade(float fade) override;
  void setAlongNormal(bool alongNormal) override { mAlongNormal = alongNormal; }

  void setSides(const std::vector<std::int8_t>& sides) override;

  void closest(int frameCount, const float* poses, const float* points, SurfaceHit* hits) override;

  void transfer(int frameCount, const SurfaceHit* hits, const float* fromPoses,
                const float* toPoses, const float* points, float* out) override;

  void rebuild(int frameCount, const SurfaceHit* hits, const float* toPoses, const float* local,
               float* out) override;

  void resolve(int frameCount, const float* poses, const SurfaceHit* hits, float offset,
               float* points, int* moved) override;

  void skinPlanes(int frameCount, const float* poses, const SurfaceHit* hits,
                  const std::int32_t* answered, const float* points, float offset, float depth,
                  float reach, float* planes) override;

  void countInside(int frameCount, DeviceArray& poses, DeviceArray& hits, DeviceArray& points,
                   int* inside) override;

  void closestBlock(int frameCount, DeviceArray& poses, DeviceArray& points,
                    DeviceArray& hits) override;

  void closestOrClearBlock(int frameCount, DeviceArray& poses, DeviceArray& points, float clearance,
                           DeviceArray& hits, int* cleared, DeviceArray* answered, bool keep,
                           float reach) override;

  void transferBlock(int frameCount, DeviceArray& hits, DeviceArray& fromPoses,
                     DeviceArray& toPoses, DeviceArray& points, DeviceArray& out) override;

  void rebuildBlock(int frameCount, DeviceArray& hits, DeviceArray& toPoses, DeviceArray& local,
                    DeviceArray& out) override;

  void resolveBlock(int frameCount, DeviceArray& poses, DeviceArray& hits, float offset,
                    DeviceArray& points, int* moved) override;

  void skinPlanesBlock(int frameCount, DeviceArray& poses, DeviceArray& hits, DeviceArray* answered,
                       DeviceArray& points, float offset, float depth, float reach,
                       DeviceArray& planes) override;

 private:
  // Glue (cl_closest.cpp).
  /// 3Vp: the floats of one pose.
  std::size_t poseValues() const { return 3 * static_cast<std::size_t>(mSearch.vertexCount()); }

  /// `array` itself when its device side is on this context; else `view` over its host copy
  /// (an array of another device, or of the host), uploaded by the kernel call that reads it.
  DeviceArray& onDevice(DeviceArray& array, DeviceArray& view);

  /// An output array as the kernels see it: `target` itself when it is on this context, else
  /// `view` over its host copy (`keep`: with its current values, for updates in place), which
  /// finishOutput() brings back. The caller sizes `target` (at least `bytes`).
  DeviceArray& outputOnDevice(DeviceArray& target, DeviceArray& view, std::size_t bytes, bool keep);

  /// Downloads an output that went through a view into its target's host copy.
  static void finishOutput(DeviceArray& used, DeviceArray& view);

  /// The raw calls' NaN and range checks on the host copies that are current (see
  /// correction::checkFinite): poses F x 3Vp, points F x 3Vd, `hitCount` hits.
  void checkInputs(const char* stage, int frameCount, DeviceArray* poses, DeviceArray* points,
                   DeviceArray* hits, std::size_t hitCount) const;

  cl::Buffer uploadBytes(const void* data, std::size_t bytes);

  /// A read-only device copy of a host table (at least one element, so empty tables work).
  cl::Buffer upload(const std::vector<std::int32_t>& table);

  // kernels/closest.cl (cl_closest.cpp).
  /// ClosestBackend::closest with the host candidate lists (ClosestOptions::kCandidates).
  void closestCandidates(int frameCount, const float* poses, const float* points, SurfaceHit* hits);

  // kernels/bvh.cl (cl_bvh.cpp).
  /// At most this many triangles per BVH leaf (measured on W1: 4 and 8 are within noise).
  static constexpr int kLeafSize = 4;

  /// The BVH query's scalars for a chunk of `frameCount` frames.
  DsBvhQueryParams queryParams(int frameCount) const;

  /// The warm start of the first block: the host's guess on its first frame (a warm start
  /// only; later blocks start from the previous block's last hits).
  void seedOnce(DeviceArray& poses, DeviceArray& points);

  /// Every node's box on every frame of `poses` (dsBvhRefit, one launch per depth) into mBoxes;
  /// kept while the poses keep their version (the resolution, its exit fade and the audit's
  /// recount read the boxes of one block).
  cl::Buffer& refitBoxes(int frameCount, DeviceArray& poses);

  /// ClosestBackend::closest through the BVH (see src/database/bvh.cpp and kernels/bvh.cl)
  /// on arrays of this context; `hits` sized F x Vd.
  void closestBvh(int frameCount, DeviceArray& poses, DeviceArray& points, DeviceArray& hits);

  // kernels/transfer.cl (cl_transfer.cpp).
  /// The sizes the transfer and rebuild kernels share.
  DsTransferParams transferParams(int frameCount) const;

  void transferOnDevice(int frameCount, DeviceArray& hits, DeviceArray& fromPoses,
                        DeviceArray& toPoses, DeviceArray& points, DeviceArray& out);

  void rebuildOnDevice(int frameCount, DeviceArray& hits, DeviceArray& toPoses, DeviceArray& local,
                       DeviceArray& out);

  // kernels/certificate.cl (cl_certificate.cpp).
  /// Every node's cone on every frame of `poses` (dsCertRefitCones after the boxes, one launch
  /// per depth) into mCones; kept, as the boxes, while the poses keep their version.
  cl::Buffer& refitCones(int frameCount, DeviceArray& poses, const cl::Buffer& boxBuffer,
                         DsCertParams params);

  /// closestOrClearBlock on arrays of this context (src/devices/certificate.cpp): the
  /// boxes and cones of every frame, the check of every point, then one BVH search over the
  /// points left. `answered` (F x Vd, or null: scratch) as for closestOrClearBlock; cleared F.
  void clearOrSearch(int frameCount, DeviceArray& poses, DeviceArray& points, float clearance,
                     float reach, DeviceArray& hits, DeviceArray* answered, bool keep,
                     int* cleared);

  // kernels/resolve.cl (cl_resolve.cpp).
  void resolveOnDevice(int frameCount, DeviceArray& poses, DeviceArray& hits, float offset,
                       DeviceArray& points, int* moved);

  /// The parameters dsResolve, dsCountInside and dsSkinPlanes share: the sizes, the offset, the
  /// side table and the direction (the others zero).
  DsResolveParams signedParams(int frameCount, float offset) const;

  /// dsSkinPlanes over every point of `frameCount` frames (arrays of this context or views).
  void skinPlanesOnDevice(int frameCount, DeviceArray& poses, DeviceArray& hits,
                          DeviceArray* answered, DeviceArray& points, float offset, float depth,
                          float reach, DeviceArray& planes);

  /// Runs dsResolve or dsCountInside (same first arguments, the side table included; dsResolve's
  /// BVH arguments are set by the caller) over every point of `frameCount` frames and reads back
  /// their per-frame counters into `counts`.
  void launchSigned(cl::Kernel& kernel, int frameCount, DeviceArray& poses, DeviceArray& hits,
                    const cl::Buffer& pointsBuffer, float offset, float fade, int* counts,
                    const char* what);

  cl::Context mContext;
  cl::Device mDevice;
  cl::CommandQueue mQueue;
  cl_util::Transfers* mTransfers = nullptr;
  bool mDouble = false;
  bool mUseBvh = true;
  std::string mName;
  cl::Program mProgram;
  cl::Kernel mClosestKernel;
  cl::Kernel mTransferKernel;
  cl::Kernel mRebuildKernel;
  cl::Kernel mResolveKernel;
  cl::Kernel mCountInsideKernel;
  cl::Kernel mSkinPlanesKernel;
  cl::Kernel mRefitKernel;
  cl::Kernel mBvhKernel;
  cl::Kernel mBvhListKernel;
  cl::Kernel mConeKernel;
  cl::Kernel mCertCheckKernel;
  cl::Kernel mCertCountKernel;
  correction::CandidateSearch mSearch;
  correction::CandidateTable mCandidates;
  cl::Buffer mTriangles;
  cl::Buffer mEdgeStart;
  cl::Buffer mEdgeTriangles;
  cl::Buffer mVertexStart;
  cl::Buffer mVertexTriangles;
  correction::BvhTables mBvh;
  cl::Buffer mNodes;
  cl::Buffer mLeafTriangles;
  cl::Buffer mPointRoot;
  cl::Buffer mSeeds;
  bool mSeeded = false;
  cl::Buffer mSides;  ///< Vd chars (ClosestBackend::setSides), or a placeholder when !mSided
  bool mSided = false;
  float mFade = 0.0f;        ///< setExitFade()
  bool mAlongNormal = true;  ///< setAlongNormal()
  bool mCertifiable = false;
  cl::Buffer mNodeTriangle;
  /// Which poses the boxes and cones were refitted on: DeviceArray::version() and the frames.
  struct Refit {
    std::uint64_t version = 0;
    int frames = 0;
    bool operator==(const Refit& other) const {
      return version == other.version && frames == other.frames;
    }
  };
  Refit mBoxesOf;
  Refit mConesOf;
  cl_util::GrowingBuffer mCones{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mSearchList{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mAnswered{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mSearchCount{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mBoxes{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mPoses{CL_MEM_READ_ONLY};  // the candidate path's
  cl_util::GrowingBuffer mPoints{CL_MEM_READ_ONLY};
  cl_util::GrowingBuffer mStart{CL_MEM_READ_ONLY};
  cl_util::GrowingBuffer mCandidateTriangles{CL_MEM_READ_ONLY};
  cl_util::GrowingBuffer mHits{CL_MEM_READ_WRITE};
  cl_util::GrowingBuffer mCounts{CL_MEM_READ_WRITE};
  // Views of the raw calls' memory (and of arrays of other devices) for the array path.
  DeviceArray mViewPoses, mViewToPoses, mViewPoints, mViewHits, mViewOut, mViewAnswered;
};

}  // namespace drivenshape
