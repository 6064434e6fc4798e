// SPDX-License-Identifier: Apache-2.0
// Meshes (OBJ), point caches (PC2, point-cache EXR, in-memory arrays) and frame ranges.
#include "binding.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <utility>

#include <drivenshape/frames.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

#include "up_axis.h"

namespace drivenshape::python {

namespace {

using Index = py::ssize_t;

// ---- Meshes -----------------------------------------------------------------------------

std::string meshRepr(const Mesh& mesh) {
  std::string groups;
  for (const std::string& name : mesh.groupNames) {
    groups += (groups.empty() ? "" : ", ") + name;
  }
  return "<drivenshape.Mesh " + std::to_string(mesh.vertexCount()) + " vertices, " +
         std::to_string(mesh.faceCount()) + " faces, " + std::to_string(mesh.triangleCount()) +
         " triangles, groups [" + groups + "]" + (mesh.hasUvs() ? ", UVs>" : ">");
}

Mesh meshFromPolygons(types::ArrayLike positions, types::ArrayLike faceStart,
                      types::ArrayLike faceVertices, types::OptionalArrayLike uvs,
                      types::OptionalArrayLike faceUvs, types::OptionalArrayLike faceGroups,
                      std::vector<std::string> groupNames) {
  Mesh mesh;
  const FloatArray points(positions, "positions");
  if (points.ndim() != 2 || points.dim(1) != 3) {
    DS_THROW(kUsage, "positions must be shaped (vertices, 3); got ", points.describe());
  }
  mesh.positions.resize(points.dim(0), 3);
  std::copy(points.data(), points.data() + points.size(), mesh.positions.data());
  mesh.faceVertices = intVector(faceVertices, "face_vertices");
  mesh.faceStart = intVector(faceStart, "face_start");
  // Blender's loop_start has one entry per face; ours has the end too.
  const int corners = static_cast<int>(mesh.faceVertices.size());
  if (mesh.faceStart.empty() || mesh.faceStart.back() != corners) {
    mesh.faceStart.push_back(corners);
  }
  const std::size_t faces = mesh.faceStart.size() - 1;
  if (!uvs.is_none()) {
    const FloatArray uvArray(uvs, "uvs");
    if (uvArray.ndim() != 2 || uvArray.dim(1) != 2) {
      DS_THROW(kUsage, "uvs must be shaped (uv count, 2); got ", uvArray.describe());
    }
    mesh.uvs.resize(static_cast<std::size_t>(uvArray.dim(0)));
    for (std::size_t i = 0; i < mesh.uvs.size(); ++i) {
      mesh.uvs[i] = Eigen::Vector2f(uvArray.data()[2 * i], uvArray.data()[2 * i + 1]);
    }
    if (faceUvs.is_none()) {
      DS_THROW(kUsage, "uvs need face_uvs: one uv index per face corner (face_vertices)");
    }
    mesh.faceUvs = intVector(faceUvs, "face_uvs");
  } else if (!faceUvs.is_none()) {
    DS_THROW(kUsage, "face_uvs given without uvs");
  }
  if (faceGroups.is_none()) {
    mesh.faceGroup.assign(faces, 0);
    if (groupNames.empty()) {
      groupNames.push_back("default");
    }
  } else {
    mesh.faceGroup = intVector(faceGroups, "face_groups");
    if (groupNames.empty()) {
      DS_THROW(kUsage, "face_groups need group_names (the name of each group id)");
    }
  }
  mesh.groupNames = std::move(groupNames);
  if (mesh.faceGroup.size() != faces) {
    DS_THROW(kUsage, "face_groups has ", mesh.faceGroup.size(), " entries for ", faces, " faces");
  }
  validateMesh(mesh, "Mesh.from_polygons");
  mesh.triangulate();
  return mesh;
}

// ---- Point caches -----------------------------------------------------------------------

/// A cache over a Python array (F, V, 3): frames first, first + 1, ... or the frames given.
/// Holds the caller's memory when it is C-contiguous float32 (no copy), else a converted copy.
class ArrayPointCache final : public PointCacheReader {
 public:
  ArrayPointCache(py::handle positions, int startFrame, py::handle frames)
      : mArray(std::in_place, positions, "cache positions"), mPath("(in-memory array)") {
    const FrameBlockShape shape = frameBlockShape(*mArray, "cache positions");
    mVertexCount = shape.vertices;
    if (frames.is_none()) {
      if (static_cast<long long>(startFrame) + shape.frames - 1 > std::numeric_limits<int>::max()) {
        DS_THROW(kUsage, "start_frame ", startFrame, " with ", shape.frames,
                 " frames runs past the last frame number, ", std::numeric_limits<int>::max());
      }
      for (int f = 0; f < shape.frames; ++f) {
        mFrames.push_back(startFrame + f);
      }
    } else {
      mFrames = frameList(frames);
      if (static_cast<int>(mFrames.size()) != shape.frames) {
        DS_THROW(kUsage, "cache positions hold ", shape.frames, " frames but ", mFrames.size(),
                 " frame numbers were given");
      }
    }
    for (std::size_t i = 0; i < mFrames.size(); ++i) {
      mOrder.emplace_back(mFrames[i], static_cast<int>(i));
    }
    std::sort(mOrder.begin(), mOrder.end());
    for (std::size_t i = 1; i < mOrder.size(); ++i) {
      if (mOrder[i].first == mOrder[i - 1].first) {
        DS_THROW(kUsage, "cache frame numbers repeat frame ", mOrder[i].first);
      }
    }
  }
  ~ArrayPointCache() override {
    // The buffer view is released with the GIL (the last owner may be a C++ object).
    py::gil_scoped_acquire gil;
    mArray = std::nullopt;
  }

  int vertexCount() const override { return mVertexCount; }
  std::vector<int> frames() const override {
    std::vector<int> sorted;
    for (const auto& entry : mOrder) {
      sorted.push_back(entry.first);
    }
    return sorted;
  }
  bool hasFrame(int frame) const override { return indexOf(frame) >= 0; }
  void readFrame(int frame, float* xyz) const override {
    const int index = indexOf(frame);
    if (index < 0) {
      DS_THROW(kInput, mPath, ": frame ", frame, " is not in the cache; it holds ",
               mOrder.empty() ? std::string("no frames") : "frames " + formatFrameRange(frames()));
    }
    const std::size_t values = 3 * static_cast<std::size_t>(mVertexCount);
    const float* source = mArray->data() + static_cast<std::size_t>(index) * values;
    std::copy(source, source + values, xyz);
  }
  const std::string& path() const override { return mPath; }
  bool copied() const { return mArray->copied(); }

 private:
  int indexOf(int frame) const {
    const auto found = std::lower_bound(mOrder.begin(), mOrder.end(), std::make_pair(frame, -1));
    return found != mOrder.end() && found->first == frame ? found->second : -1;
  }

  std::optional<FloatArray> mArray;
  std::string mPath;
  int mVertexCount = 0;
  std::vector<int> mFrames;
  std::vector<std::pair<int, int>> mOrder;  ///< (frame, index), sorted
};

types::Float32Array readCacheFrames(const PointCacheReader& cache, const std::vector<int>& frames) {
  std::vector<float> values;
  {
    py::gil_scoped_release release;
    values = readFrames(cache, frames);
  }
  return types::Float32Array(
      ownedArray(std::move(values),
                 {static_cast<Index>(frames.size()), static_cast<Index>(cache.vertexCount()), 3}));
}

/// (positions (F, V, 3), start frame, sample rate) of every sample of a PC2 file, including
/// samples between whole frames (which openPc2's reader does not give). The samples are read
/// as they are stored, little-endian, which is the host order of every platform this builds
/// for (x86-64, arm64).
types::Pc2Samples readPc2(const std::string& path) {
  std::vector<float> values;
  float header[2] = {0.0f, 0.0f};
  int points = 0;
  int samples = 0;
  {
    py::gil_scoped_release release;
    // openPc2 validates the header and the file size and names what is wrong.
    points = openPc2(path)->vertexCount();
    std::ifstream file(path, std::ios::binary);
    char bytes[32];
    if (!file.read(bytes, sizeof(bytes))) {
      DS_THROW(kInput, path, ": cannot read the PC2 header");
    }
    std::memcpy(header, bytes + 20, sizeof(header));
    std::memcpy(&samples, bytes + 28, sizeof(samples));
    values.resize(static_cast<std::size_t>(samples) * static_cast<std::size_t>(points) * 3);
    if (!file.read(reinterpret_cast<char*>(values.data()),
                   static_cast<std::streamsize>(values.size() * sizeof(float)))) {
      DS_THROW(kInput, path, ": cannot read the PC2 samples (was the file changed?)");
    }
  }
  py::object array = ownedArray(std::move(values), {samples, points, 3});
  return types::Pc2Samples(py::make_tuple(array, header[0], header[1]));
}

types::JsonDict exrInfoDict(const ExrPointCacheInfo& info) {
  py::dict out;
  out["vertex_count"] = info.vertexCount;
  out["width"] = info.width;
  out["frame"] = info.frame;
  out["topology_hash"] = info.topologyHash;
  out["settings_hash"] = info.settingsHash;
  out["tool_version"] = info.toolVersion;
  out["frames_per_second"] = info.framesPerSecond;
  out["bounds_min"] = py::make_tuple(info.bounds.min.x(), info.bounds.min.y(), info.bounds.min.z());
  out["bounds_max"] = py::make_tuple(info.bounds.max.x(), info.bounds.max.y(), info.bounds.max.z());
  out["has_normals"] = info.hasNormals;
  out["compression"] = exrCompressionName(info.compression);
  out["pixels_crc"] = info.hasPixelsCrc ? py::object(py::int_(info.pixelsCrc)) : py::none();
  out["string_attributes"] = info.stringAttributes;
  return types::JsonDict(out);
}

/// `convert_up_axis`: a float32 copy of positions (..., 3) rotated between the up axes.
types::Float32Array convertUpAxisCopy(types::ArrayLike positions, const std::string& fromAxis,
                                      const std::string& toAxis) {
  const UpAxis from = parseUpAxis(fromAxis, "from_axis");
  const UpAxis to = parseUpAxis(toAxis, "to_axis");
  const FloatArray array(positions, "positions");
  if (array.ndim() < 1 || array.dim(array.ndim() - 1) != 3) {
    DS_THROW(kUsage, "positions must be shaped (..., 3); got ", array.describe());
  }
  std::vector<py::ssize_t> shape;
  for (int axis = 0; axis < array.ndim(); ++axis) {
    shape.push_back(array.dim(axis));
  }
  std::vector<float> xyz(array.data(), array.data() + array.size());
  convertUpAxis(xyz.data(), xyz.size() / 3, from, to);
  return types::Float32Array(ownedArray(std::move(xyz), std::move(shape)));
}

/// The mesh's arrays as properties: read-only numpy views of its own memory (no copy).
void bindMeshArrays(py::class_<Mesh>& meshClass) {
  meshClass
      .def_property_readonly(
          "positions",
          [](py::object self) {
            const Mesh& mesh = self.cast<const Mesh&>();
            return types::Float32Array(
                viewArray(mesh.positions.data(), {mesh.positions.rows(), 3}, self));
          },
          "(V, 3) float32, read-only view")
      .def_property_readonly(
          "triangles",
          [](py::object self) {
            const Mesh& mesh = self.cast<const Mesh&>();
            return types::Int32Array(
                viewArray(mesh.triangles.data(), {mesh.triangles.rows(), 3}, self));
          },
          "(T, 3) int32 fan triangles, read-only view")
      .def_property_readonly(
          "triangle_face",
          [](py::object self) {
            const Mesh& mesh = self.cast<const Mesh&>();
            return types::Int32Array(viewArray(
                mesh.triangleFace.data(), {static_cast<Index>(mesh.triangleFace.size())}, self));
          },
          "(T,) int32: the face each triangle came from")
      .def_property_readonly(
          "face_start",
          [](py::object self) {
            const Mesh& mesh = self.cast<const Mesh&>();
            return types::Int32Array(viewArray(mesh.faceStart.data(),
                                               {static_cast<Index>(mesh.faceStart.size())}, self));
          },
          "(F + 1,) int32 offsets into face_vertices")
      .def_property_readonly(
          "face_vertices",
          [](py::object self) {
            const Mesh& mesh = self.cast<const Mesh&>();
            return types::Int32Array(viewArray(
                mesh.faceVertices.data(), {static_cast<Index>(mesh.faceVertices.size())}, self));
          },
          "int32 vertex ids of every face corner, concatenated")
      .def_property_readonly(
          "faces",
          [](py::object self) {
            return types::Faces(
                py::make_tuple(self.attr("face_start"), self.attr("face_vertices")));
          },
          "(face_start, face_vertices)")
      .def_property_readonly(
          "uvs",
          [](py::object self) {
            const Mesh& mesh = self.cast<const Mesh&>();
            return types::Float32Array(viewArray(mesh.uvs.empty() ? nullptr : mesh.uvs[0].data(),
                                                 {static_cast<Index>(mesh.uvs.size()), 2}, self));
          },
          "(U, 2) float32 texture coordinates (may be empty)")
      .def_property_readonly(
          "face_uvs",
          [](py::object self) {
            const Mesh& mesh = self.cast<const Mesh&>();
            return types::Int32Array(
                viewArray(mesh.faceUvs.data(), {static_cast<Index>(mesh.faceUvs.size())}, self));
          },
          "int32 uv id per face corner (parallel to face_vertices; -1 = none), or empty")
      .def_property_readonly(
          "face_groups",
          [](py::object self) {
            const Mesh& mesh = self.cast<const Mesh&>();
            return types::Int32Array(viewArray(mesh.faceGroup.data(),
                                               {static_cast<Index>(mesh.faceGroup.size())}, self));
          },
          "(F,) int32 group id of each face (index into group_names)");
}

void bindPointCacheClass(py::module_& module) {
  py::class_<PointCacheReader, std::shared_ptr<PointCacheReader>>(
      module, "PointCache",
      "Frames of vertex positions: a PC2 file, a point-cache EXR sequence "
      "(open_point_cache) or an in-memory array (PointCache.from_array).")
      .def_static(
          "from_array",
          [](types::ArrayLike positions, types::Frame startFrame, types::OptionalFrames frames) {
            return makeArrayCache(positions, frameNumber(startFrame, "start_frame"), frames);
          },
          py::arg("positions"), py::arg("start_frame") = 1, py::arg("frames") = py::none(),
          "A cache over positions (F, V, 3): frames start_frame, start_frame + 1, ... or the "
          "frame numbers given. C-contiguous float32 arrays are used in place (do not change "
          "them while the cache is in use); other arrays are converted once.")
      .def_property_readonly("vertex_count", &PointCacheReader::vertexCount)
      .def_property_readonly("frames", &PointCacheReader::frames, "frames it holds, ascending")
      .def_property_readonly("path", &PointCacheReader::path)
      .def(
          "has_frame",
          [](const PointCacheReader& cache, types::Frame frame) {
            return cache.hasFrame(frameNumber(frame, "frame"));
          },
          py::arg("frame"))
      .def(
          "read",
          [](const PointCacheReader& cache, types::Frame frameObject) {
            const int frame = frameNumber(frameObject, "frame");
            std::vector<float> xyz(3 * static_cast<std::size_t>(cache.vertexCount()));
            {
              py::gil_scoped_release release;
              cache.readFrame(frame, xyz.data());
            }
            return types::Float32Array(ownedArray(std::move(xyz), {cache.vertexCount(), 3}));
          },
          py::arg("frame"), "(V, 3) float32 positions of one frame")
      .def(
          "read_frames",
          [](const PointCacheReader& cache, types::Frames frames) {
            return readCacheFrames(cache, frameList(frames));
          },
          py::arg("frames"), "(F, V, 3) float32 positions of the frames, in the order given")
      .def("__repr__", [](const PointCacheReader& cache) {
        return "<drivenshape.PointCache '" + cache.path() + "', " +
               std::to_string(cache.vertexCount()) + " vertices, frames " +
               formatFrameRange(cache.frames()) + ">";
      });
}

/// Error(kInput) naming `what`, the frame and the vertex of the first value of `values`
/// ((F, V, 3) or (V, 3)) that is not finite: a writer never stores NaN or infinity, which
/// every reader of the file would refuse or pass on.
void requireFinite(const float* values, py::ssize_t count, int vertices, const char* what) {
  const float* end = values + count;
  const float* bad = std::find_if(values, end, [](float v) { return !std::isfinite(v); });
  if (bad != end) {
    const py::ssize_t vertex = (bad - values) / 3;
    DS_THROW(kInput, what, ": the value of frame index ", vertex / std::max(vertices, 1),
             ", vertex ", vertex % std::max(vertices, 1), " is ", *bad,
             "; a cache holds finite positions only");
  }
}

/// The largest frame number magnitude a PC2 sample maps to (the reader's bound, src/io/pc2.cpp).
constexpr double kPc2FrameBound = 2.0e9;

/// `write_point_cache_exr`: one frame of positions (V, 3) and optional normals.
void writeExrFrame(types::Path path, types::ArrayLike positions, types::OptionalArrayLike normals,
                   types::Frame frame, types::WholeNumber width, const std::string& compression,
                   std::uint64_t topology, std::uint64_t settings, double fps,
                   std::map<std::string, std::string> attributes, bool sync,
                   const std::string& zipEncoder) {
  const std::string file = pathString(path);
  ExrWriteOptions options;
  // Before anything is allocated: the writer pads every row out to the full width.
  options.width = static_cast<int>(wholeNumber(width, "width", 1, kMaxPointCacheExrWidth));
  options.frame = frameNumber(frame, "frame");
  const FloatArray xyz(positions, "positions");
  if (xyz.ndim() != 2 || xyz.dim(1) != 3) {
    DS_THROW(kUsage, "positions must be shaped (vertices, 3); got ", xyz.describe());
  }
  if (xyz.dim(0) == 0) {
    DS_THROW(kUsage, "positions hold no vertices (", xyz.describe(),
             "); a point-cache EXR holds at least one");
  }
  requireFinite(xyz.data(), xyz.size(), static_cast<int>(xyz.dim(0)), "positions");
  std::optional<FloatArray> normalArray;
  if (!normals.is_none()) {
    normalArray.emplace(normals, "normals");
    if (normalArray->ndim() != 2 || normalArray->dim(0) != xyz.dim(0) || normalArray->dim(1) != 3) {
      DS_THROW(kUsage, "normals must be shaped like positions ", xyz.describe(), "; got ",
               normalArray->describe());
    }
    requireFinite(normalArray->data(), normalArray->size(), static_cast<int>(xyz.dim(0)),
                  "normals");
  }
  if (!(fps > 0.0) || !std::isfinite(fps)) {
    DS_THROW(kUsage, "frames_per_second ", fps, " is not a positive finite number");
  }
  options.compression = parseExrCompression(compression);
  options.zipEncoder = parseZipEncoder(zipEncoder, "zip_encoder");
  options.topologyHash = topology;
  options.settingsHash = settings;
  options.framesPerSecond = fps;
  options.stringAttributes.assign(attributes.begin(), attributes.end());
  options.syncToDisk = sync;
  py::gil_scoped_release release;
  writePointCacheExr(file, static_cast<int>(xyz.dim(0)), xyz.data(),
                     normalArray ? normalArray->data() : nullptr, options);
}

/// Opening caches, and PC2 files read and written whole.
void bindCacheFiles(py::module_& module) {
  module.def(
      "open_point_cache",
      [](types::Path spec, std::uint64_t expectedTopology) {
        const std::string text = pathString(spec);
        py::gil_scoped_release release;
        return std::shared_ptr<PointCacheReader>(openPointCache(text, expectedTopology));
      },
      py::arg("spec"), py::arg("expected_topology") = 0,
      "Opens a .pc2 file or a point-cache EXR sequence pattern (out.####.exr, %04d, $F4); "
      "with expected_topology, every EXR's topology hash is checked.");

  module.def(
      "read_pc2", [](types::Path path) { return readPc2(pathString(path)); }, py::arg("path"),
      "(positions (F, V, 3) float32, start_frame, sample_rate) of every sample of a PC2 file");
  module.def(
      "write_pc2",
      [](types::Path path, types::ArrayLike positions, float startFrame, float sampleRate) {
        const std::string file = pathString(path);
        const FloatArray array(positions, "positions");
        const FrameBlockShape shape = frameBlockShape(array, "positions");
        requireFinite(array.data(), array.size(), shape.vertices, "positions");
        // Samples beyond the frames a PC2 reader maps would be written and never read.
        const double last = static_cast<double>(startFrame) +
                            static_cast<double>(std::max(shape.frames - 1, 0)) * sampleRate;
        if (!(std::abs(static_cast<double>(startFrame)) < kPc2FrameBound) ||
            !(std::abs(last) < kPc2FrameBound)) {
          DS_THROW(kUsage, "start_frame ", static_cast<double>(startFrame), " with ", shape.frames,
                   " samples at sample_rate ", sampleRate, " reaches frame ", last,
                   ", beyond the frames a PC2 reader maps (|frame| < ", kPc2FrameBound, ")");
        }
        py::gil_scoped_release release;
        writePc2(file, shape.vertices, startFrame, shape.frames, array.data(), sampleRate);
      },
      py::arg("path"), py::arg("positions"), py::arg("start_frame") = 1.0f,
      py::arg("sample_rate") = 1.0f,
      "Writes positions (F, V, 3) as PC2 (atomically), sample s at start_frame + s * "
      "sample_rate.");
}

/// Point-cache EXR frames (docs/formats.md).
void bindPointCacheExr(py::module_& module) {
  module.def("write_point_cache_exr", &writeExrFrame, py::arg("path"), py::arg("positions"),
             py::arg("normals") = py::none(), py::arg("frame") = 0, py::arg("width") = 1024,
             py::arg("compression") = "zip", py::arg("topology_hash") = 0,
             py::arg("settings_hash") = 0, py::arg("frames_per_second") = 24.0,
             py::arg("string_attributes") = std::map<std::string, std::string>(),
             py::arg("sync") = true, py::arg("zip_encoder") = "libdeflate",
             "Writes one point-cache EXR frame atomically: positions (V, 3), optional normals, "
             "compression zip|none|zips|piz, zip_encoder libdeflate|openexr (who deflates zip and "
             "zips), header attributes as in docs/formats.md.");
  module.def(
      "read_point_cache_exr",
      [](types::Path path, int expectedVertexCount, std::uint64_t expectedTopology) {
        const std::string file = pathString(path);
        std::vector<float> xyz;
        ExrPointCacheInfo info;
        {
          py::gil_scoped_release release;
          info = readPointCacheExr(file, xyz, expectedVertexCount, expectedTopology);
        }
        const int count = info.vertexCount;
        return types::ExrFrame(
            py::make_tuple(ownedArray(std::move(xyz), {count, 3}), exrInfoDict(info)));
      },
      py::arg("path"), py::arg("expected_vertex_count") = 0, py::arg("expected_topology") = 0,
      "(positions (V, 3) float32, header dict) of one point-cache EXR; a nonzero expected "
      "vertex count or topology hash that differs from the header is an Error.");
  module.def(
      "read_point_cache_exr_info",
      [](types::Path path) {
        const std::string file = pathString(path);
        ExrPointCacheInfo info;
        {
          py::gil_scoped_release release;
          info = readPointCacheExrInfo(file);
        }
        return exrInfoDict(info);
      },
      py::arg("path"), "The header of one point-cache EXR as a dict.");
}

void bindFrameRanges(py::module_& module) {
  module.def("parse_frame_range", &parseFrameRange, py::arg("text"),
             "'1001-1100', '1001-1100x2', '1001,1005,1010-1020' -> list of frames");
  module.def(
      "format_frame_range",
      [](types::Frames frames) { return formatFrameRange(frameList(frames)); }, py::arg("frames"));
  module.def(
      "expand_frame_pattern",
      [](const std::string& pattern, types::Frame frame) {
        return expandFramePattern(pattern, frameNumber(frame, "frame"));
      },
      py::arg("pattern"), py::arg("frame"),
      "'out.####.exr', 12 -> 'out.0012.exr' (also %04d and $F4)");
}

}  // namespace

std::shared_ptr<PointCacheReader> makeArrayCache(py::handle positions, int startFrame,
                                                 py::handle frames) {
  return std::make_shared<ArrayPointCache>(positions, startFrame, frames);
}

void bindMeshes(py::module_& module) {
  py::class_<Mesh> meshClass(module, "Mesh",
                             "A polygon mesh: positions, faces of any size, UVs, face groups, "
                             "and the fan triangulation the correction uses. Array properties "
                             "are read-only views of the mesh's own memory (no copy).");
  meshClass
      .def_static("from_polygons", &meshFromPolygons, py::arg("positions"), py::arg("face_start"),
                  py::arg("face_vertices"), py::arg("uvs") = py::none(),
                  py::arg("face_uvs") = py::none(), py::arg("face_groups") = py::none(),
                  py::arg("group_names") = std::vector<std::string>(),
                  "Mesh from positions (V, 3), face_start (F + 1 offsets, or F as Blender's "
                  "loop_start) and face_vertices (the corners' vertex ids, concatenated); "
                  "optional uvs (U, 2) with face_uvs (one uv id per corner), face_groups (F "
                  "group ids) with group_names. Validated like an OBJ (Error kind 'input').")
      .def_property_readonly("vertex_count", &Mesh::vertexCount)
      .def_property_readonly("face_count", &Mesh::faceCount)
      .def_property_readonly("triangle_count", &Mesh::triangleCount)
      .def_property_readonly(
          "edges",
          [](const Mesh& mesh) {
            std::vector<int> ids;
            for (const MeshEdge& edge : meshEdges(mesh)) {
              ids.insert(ids.end(), edge.begin(), edge.end());
            }
            const auto count = static_cast<py::ssize_t>(ids.size() / 2);
            return types::Int32Array(ownedArray(std::move(ids), {count, 2}));
          },
          "(E, 2) int32: the unique edges of the faces (polygon sides, not the fan "
          "triangulation's diagonals), the smaller vertex id first, sorted; computed anew on "
          "each access (the edges eval's strain measures)");
  bindMeshArrays(meshClass);
  meshClass.def_readonly("group_names", &Mesh::groupNames)
      .def_property_readonly("has_uvs", &Mesh::hasUvs)
      .def_property_readonly(
          "topology_hash", [](const Mesh& mesh) { return topologyHash(mesh); },
          "hash of the vertex count and faces (as EXR headers and databases record it)")
      .def("__repr__", &meshRepr);

  module.def(
      "read_obj",
      [](types::Path path) {
        const std::string file = pathString(path);
        py::gil_scoped_release release;
        return readObj(file);
      },
      py::arg("path"), "Reads an OBJ (vertex order kept exactly as in the file).");
  module.def(
      "write_obj",
      [](types::Path path, const Mesh& mesh) {
        const std::string file = pathString(path);
        requireFinite(mesh.positions.data(), mesh.positions.size(), mesh.vertexCount(),
                      "the mesh's positions");
        py::gil_scoped_release release;
        writeObj(file, mesh);
      },
      py::arg("path"), py::arg("mesh"), "Writes positions, faces, UVs and groups as OBJ.");
  module.def("convert_up_axis", &convertUpAxisCopy, py::arg("positions"), py::arg("from_axis"),
             py::arg("to_axis"),
             "A float32 copy of positions (..., 3) rotated from the up axis from_axis to to_axis "
             "('Y' or 'Z'): Z -> Y is (x, y, z) -> (x, z, -y), Y -> Z its inverse (x, y, z) -> "
             "(x, -z, y). Values are only moved and negated, never rounded: the conversion is "
             "exact.");
}

void bindPointCaches(py::module_& module) {
  bindPointCacheClass(module);
  bindCacheFiles(module);
  bindPointCacheExr(module);
  bindFrameRanges(module);
}

}  // namespace drivenshape::python
