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

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/evaluator.h>
#include <drivenshape/point_cache.h>

namespace drivenshape::python {

namespace py = pybind11;

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

/// The Evaluator of a drivenshape.Evaluator; Error(kUsage) for any other object.
const Evaluator& evaluatorOf(py::handle object);

}  // namespace drivenshape::python
