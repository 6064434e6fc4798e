// SPDX-License-Identifier: Apache-2.0
#pragma once

// Shared by the translation units of the `_drivenshape` Python extension: how C++ memory is
// shown to Python as numpy arrays without a copy, and how Python arrays are read without one.
//
// pybind11's own numpy layer (pybind11/numpy.h, 2.10 in Debian 12) reads numpy's C structs
// directly and breaks with numpy 2, while Blender 3.4 on Debian runs numpy 1.24: the module
// therefore speaks only the buffer protocol (PEP 3118), which both numpy versions share, and
// calls numpy's Python API (asarray, ascontiguousarray) for the rest.

#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <cstddef>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/point_cache.h>

namespace drivenshape::python {

namespace py = pybind11;

/// A Python argument or result that the binding reads or builds itself (a path, frames, an
/// array), with the Python type it stands for in its signature: help(), the docstrings and so
/// the stubs (apps/python/drivenshape/_drivenshape.pyi, generated from them) show `Name::name`
/// instead of pybind11's `object`/`handle`. It converts and checks nothing: any object is
/// passed through unchanged, and the binding checks it with its own messages as before.
template <typename Name>
class Typed : public py::object {
 public:
  using py::object::object;
  Typed() = default;
  explicit Typed(py::object value) : py::object(std::move(value)) {}
  static bool check_(py::handle object) { return object.ptr() != nullptr; }
};

/// The Python types of Typed, spelled as the stubs write them (PEP 604 unions, qualified
/// names; classes of this module by their own name).
namespace type_names {
#define DS_PYTHON_TYPE(Tag, spelling)                              \
  struct Tag {                                                     \
    static constexpr auto name = py::detail::const_name(spelling); \
  }
#define DS_PYTHON_FRAMES                                                     \
  "typing.SupportsIndex | collections.abc.Sequence[typing.SupportsIndex] | " \
  "numpy.typing.NDArray[numpy.integer[typing.Any]]"
#define DS_PYTHON_CACHE "PointCache | str | os.PathLike[str] | numpy.typing.ArrayLike"
#define DS_PYTHON_FLOAT32 "numpy.typing.NDArray[numpy.float32]"
#define DS_PYTHON_INT32 "numpy.typing.NDArray[numpy.int32]"
#define DS_PYTHON_FLOAT64 "numpy.typing.NDArray[numpy.float64]"
// Inputs: one frame or several (frameNumber, frameList); arrays that are read as float32 or
// int32, any array-like converted once (FloatArray, intVector).
DS_PYTHON_TYPE(Path, "str | os.PathLike[str]");
DS_PYTHON_TYPE(Frame, "typing.SupportsIndex");
DS_PYTHON_TYPE(WholeNumber, "typing.SupportsIndex");
DS_PYTHON_TYPE(Frames, DS_PYTHON_FRAMES);
DS_PYTHON_TYPE(OptionalFrames, DS_PYTHON_FRAMES " | None");
DS_PYTHON_TYPE(ArrayLike, "numpy.typing.ArrayLike");
DS_PYTHON_TYPE(OptionalArrayLike, "numpy.typing.ArrayLike | None");
DS_PYTHON_TYPE(MeshSource, "Mesh | str | os.PathLike[str]");
DS_PYTHON_TYPE(CacheSource, DS_PYTHON_CACHE);
DS_PYTHON_TYPE(ReferenceClips, "collections.abc.Iterable[tuple[" DS_PYTHON_CACHE
                               ", " DS_PYTHON_CACHE "] | tuple[" DS_PYTHON_CACHE
                               ", " DS_PYTHON_CACHE ", " DS_PYTHON_FRAMES " | None]] | None");
DS_PYTHON_TYPE(TextOutput, "typing.TextIO | None");
DS_PYTHON_TYPE(ReportSource, "str | os.PathLike[str] | dict[str, typing.Any]");
DS_PYTHON_TYPE(ArrayLikes, "collections.abc.Sequence[numpy.typing.ArrayLike]");
DS_PYTHON_TYPE(EvaluatorObject, "Evaluator");
// Outputs, and evaluate_into's `out` (which must already be float32).
DS_PYTHON_TYPE(Float32Array, DS_PYTHON_FLOAT32);
DS_PYTHON_TYPE(Int32Array, DS_PYTHON_INT32);
DS_PYTHON_TYPE(Float64Array, DS_PYTHON_FLOAT64);
DS_PYTHON_TYPE(Faces, "tuple[" DS_PYTHON_INT32 ", " DS_PYTHON_INT32 "]");
DS_PYTHON_TYPE(Pc2Samples, "tuple[" DS_PYTHON_FLOAT32 ", float, float]");
DS_PYTHON_TYPE(ExrFrame, "tuple[" DS_PYTHON_FLOAT32 ", dict[str, typing.Any]]");
DS_PYTHON_TYPE(Evaluation, "tuple[" DS_PYTHON_FLOAT32 ", list[FrameRecord]]");
DS_PYTHON_TYPE(Records, "list[FrameRecord]");
DS_PYTHON_TYPE(JsonDict, "dict[str, typing.Any]");
DS_PYTHON_TYPE(JsonList, "list[dict[str, typing.Any]]");
DS_PYTHON_TYPE(TransferCounts, "dict[str, int]");
DS_PYTHON_TYPE(StrainDict, "dict[str, float]");
DS_PYTHON_TYPE(Spliced, "tuple[" DS_PYTHON_FLOAT32 ", list[str]]");
DS_PYTHON_TYPE(Sources, "list[str]");
#undef DS_PYTHON_TYPE
#undef DS_PYTHON_FRAMES
#undef DS_PYTHON_CACHE
#undef DS_PYTHON_FLOAT32
#undef DS_PYTHON_INT32
#undef DS_PYTHON_FLOAT64
}  // namespace type_names

/// Arguments and results by their Python type: `types::Path path`.
namespace types {
using Path = Typed<type_names::Path>;
using Frame = Typed<type_names::Frame>;
using WholeNumber = Typed<type_names::WholeNumber>;
using Frames = Typed<type_names::Frames>;
using OptionalFrames = Typed<type_names::OptionalFrames>;
using ArrayLike = Typed<type_names::ArrayLike>;
using OptionalArrayLike = Typed<type_names::OptionalArrayLike>;
using MeshSource = Typed<type_names::MeshSource>;
using CacheSource = Typed<type_names::CacheSource>;
using ReferenceClips = Typed<type_names::ReferenceClips>;
using TextOutput = Typed<type_names::TextOutput>;
using ReportSource = Typed<type_names::ReportSource>;
using ArrayLikes = Typed<type_names::ArrayLikes>;
using EvaluatorObject = Typed<type_names::EvaluatorObject>;
using Float32Array = Typed<type_names::Float32Array>;
using Int32Array = Typed<type_names::Int32Array>;
using Float64Array = Typed<type_names::Float64Array>;
using Faces = Typed<type_names::Faces>;
using Pc2Samples = Typed<type_names::Pc2Samples>;
using ExrFrame = Typed<type_names::ExrFrame>;
using Evaluation = Typed<type_names::Evaluation>;
using Records = Typed<type_names::Records>;
using JsonDict = Typed<type_names::JsonDict>;
using JsonList = Typed<type_names::JsonList>;
using TransferCounts = Typed<type_names::TransferCounts>;
using StrainDict = Typed<type_names::StrainDict>;
using Spliced = Typed<type_names::Spliced>;
using Sources = Typed<type_names::Sources>;
}  // namespace types

/// A direction (x, y, z): read as pybind11 reads std::array<double, 3> (a sequence of three
/// numbers, else a TypeError), shown as a Python type (pybind11 says `list[float[3]]`).
struct Vector3 {
  std::array<double, 3> xyz{};
};

/// Memory handed to numpy: a buffer-protocol object that keeps the memory alive, either by
/// owning it (`keep`, e.g. the cloth of an evaluate() call) or by holding the Python object
/// that owns it (`parent`, e.g. a Mesh whose positions are shown). numpy.asarray() of it is
/// the array the caller sees; the array's `.base` is a memoryview whose `.obj` is this object.
///
///   shape (d0, d1, ..., dn), C order: element [i0, ..., in] at data + sum(ik * stride_k)
class ArrayBuffer {
 public:
  ArrayBuffer(std::shared_ptr<void> keep, py::object parent, void* data, std::size_t itemSize,
              std::string format, std::vector<py::ssize_t> shape, bool readOnly);
  py::buffer_info info() const;
  const std::vector<py::ssize_t>& shape() const { return mShape; }

 private:
  std::shared_ptr<void> mKeep;
  py::object mParent;
  void* mData;
  std::size_t mItemSize;
  std::string mFormat;
  std::vector<py::ssize_t> mShape;
  bool mReadOnly;
};

/// A numpy array that owns `values` (moved, not copied), of the given C-order shape.
template <typename T>
py::object ownedArray(std::vector<T>&& values, std::vector<py::ssize_t> shape);
/// A numpy array that owns `data` (at least the product of `shape` elements).
py::object ownedFloatArray(std::shared_ptr<float[]> data, std::vector<py::ssize_t> shape);
/// A read-only numpy view of memory owned by the Python object `parent` (kept alive).
template <typename T>
py::object viewArray(const T* data, std::vector<py::ssize_t> shape, py::handle parent);

/// A C-contiguous float32 view of a Python array-like: the caller's own memory when it already
/// is one (numpy float32, C order), else a converted copy (numpy.ascontiguousarray), which
/// `copied()` reports. With `writable`, nothing is converted: anything but a writable
/// C-contiguous float32 buffer is refused with Error(kUsage). `what` names it in messages.
/// Must be created and destroyed with the GIL held; data() may be used without it.
class FloatArray {
 public:
  FloatArray(py::handle object, const std::string& what, bool writable = false);
  const float* data() const { return static_cast<const float*>(mInfo.ptr); }
  float* mutableData() const { return static_cast<float*>(mInfo.ptr); }
  int ndim() const { return static_cast<int>(mInfo.ndim); }
  py::ssize_t dim(int axis) const { return mInfo.shape[static_cast<std::size_t>(axis)]; }
  py::ssize_t size() const { return mInfo.size; }
  bool copied() const { return mCopied; }
  /// "(2, 2146, 3) float32" for messages.
  std::string describe() const;

 private:
  py::object mObject;
  py::buffer_info mInfo;
  bool mCopied = false;
};

/// Frames x vertices x 3 of a driver or cache array: (F, V, 3), or (V, 3) for one frame.
/// Throws Error(kUsage) naming `what` for any other shape.
struct FrameBlockShape {
  int frames = 0;
  int vertices = 0;
};
FrameBlockShape frameBlockShape(const FloatArray& array, const std::string& what);

/// int32 values of an integer array-like (copied once, through numpy).
std::vector<int> intVector(py::handle object, const std::string& what);

/// `object` as a whole number within [min, max]: a Python int of any size, anything with
/// __index__ (numpy integers) or a float with a whole value; bools, fractions and other types
/// are refused. Error(kUsage) naming `what` and the value, with the range when it is outside.
long long wholeNumber(py::handle object, const std::string& what, long long min, long long max);

/// A frame number: a whole number within the library's frame numbers (a C++ int), checked
/// before conversion (pybind11 and numpy would wrap 2**32 + 5 to 5). Error(kUsage) naming
/// `what` and the value.
int frameNumber(py::handle object, const std::string& what);

/// Frame numbers from one frame or a sequence or array of them, each checked as frameNumber:
/// the one helper every binding that takes frames uses.
std::vector<int> frameList(py::handle object, const std::string& what = "frames");

/// The short name of an error code, as `drivenshape.Error.kind` spells it ("input", ...).
const char* errorKind(ErrorCode code);

/// Python path-like (str or os.PathLike) to a string; other types raise TypeError.
std::string pathString(py::handle object);
bool isPathLike(py::handle object);

/// A PointCache over a Python array (F, V, 3) (PointCache.from_array).
std::shared_ptr<PointCacheReader> makeArrayCache(py::handle positions, int startFrame,
                                                 py::handle frames);

// The binding of each part of the library, called once from the module's init.
void bindMeshes(py::module_& module);
void bindPointCaches(py::module_& module);
void bindDatabase(py::module_& module);
void bindEvaluator(py::module_& module);
void bindShotPlan(py::module_& module);
void bindSimulation(py::module_& module);

/// The Evaluator of a drivenshape.Evaluator; Error(kUsage) for any other object.
const Evaluator& evaluatorOf(py::handle object);

}  // namespace drivenshape::python

namespace pybind11::detail {
template <typename Name>
struct handle_type_name<drivenshape::python::Typed<Name>> {
  static constexpr auto name = Name::name;
};

template <>
struct type_caster<drivenshape::python::Vector3> {
  using Array = std::array<double, 3>;
  PYBIND11_TYPE_CASTER(drivenshape::python::Vector3, const_name("collections.abc.Sequence[float]"));
  bool load(handle source, bool convert) {
    make_caster<Array> array;
    if (!array.load(source, convert)) {
      return false;
    }
    value.xyz = cast_op<Array&&>(std::move(array));
    return true;
  }
  static handle cast(const drivenshape::python::Vector3& vector, return_value_policy, handle) {
    return pybind11::make_tuple(vector.xyz[0], vector.xyz[1], vector.xyz[2]).release();
  }
};
}  // namespace pybind11::detail
