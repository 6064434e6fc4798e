// SPDX-License-Identifier: Apache-2.0
// The `_drivenshape` extension: the module, its exception type, and the array plumbing the
// other binding files share (binding.h). The pure-Python package `drivenshape` re-exports it.
#include "binding.h"
#include "text.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <sstream>

#include <drivenshape/version.h>

namespace drivenshape::python {

ArrayBuffer::ArrayBuffer(std::shared_ptr<void> keep, py::object parent, void* data,
                         std::size_t itemSize, std::string format, std::vector<py::ssize_t> shape,
                         bool readOnly)
    : mKeep(std::move(keep)),
      mParent(std::move(parent)),
      mData(data),
      mItemSize(itemSize),
      mFormat(std::move(format)),
      mShape(std::move(shape)),
      mReadOnly(readOnly) {
  // numpy wants a valid pointer even for an empty array.
  static std::uint64_t emptyStorage = 0;
  if (mData == nullptr) {
    mData = &emptyStorage;
    mReadOnly = true;
  }
}

py::buffer_info ArrayBuffer::info() const {
  std::vector<py::ssize_t> strides(mShape.size());
  py::ssize_t stride = static_cast<py::ssize_t>(mItemSize);
  for (std::size_t axis = mShape.size(); axis-- > 0;) {
    strides[axis] = stride;
    stride *= mShape[axis];
  }
  return py::buffer_info(mData, static_cast<py::ssize_t>(mItemSize), mFormat,
                         static_cast<py::ssize_t>(mShape.size()), mShape, strides, mReadOnly);
}

namespace {

py::object asNumpy(ArrayBuffer buffer) {
  return py::module_::import("numpy").attr("asarray")(py::cast(std::move(buffer)));
}

bool isFloat32Format(const std::string& format) {
  return format == "f" || format == "<f" || format == "=f" || format == "@f";
}

std::string shapeText(const py::buffer_info& info) {
  std::ostringstream text;
  text << "(";
  for (std::size_t axis = 0; axis < info.shape.size(); ++axis) {
    text << (axis > 0 ? ", " : "") << info.shape[axis];
  }
  text << (info.shape.size() == 1 ? ",)" : ")");
  return text.str();
}

bool isCContiguous(const py::buffer_info& info) {
  py::ssize_t stride = info.itemsize;
  for (std::size_t axis = info.shape.size(); axis-- > 0;) {
    if (info.shape[axis] != 1 && info.strides[axis] != stride) {
      return false;
    }
    stride *= info.shape[axis];
  }
  return true;
}

}  // namespace

template <typename T>
py::object ownedArray(std::vector<T>&& values, std::vector<py::ssize_t> shape) {
  auto owner = std::make_shared<std::vector<T>>(std::move(values));
  void* data = owner->empty() ? nullptr : owner->data();
  return asNumpy(ArrayBuffer(std::move(owner), py::none(), data, sizeof(T),
                             py::format_descriptor<T>::format(), std::move(shape), false));
}

py::object ownedFloatArray(std::shared_ptr<float[]> data, std::vector<py::ssize_t> shape) {
  void* pointer = data.get();
  return asNumpy(ArrayBuffer(std::shared_ptr<void>(data, pointer), py::none(), pointer,
                             sizeof(float), py::format_descriptor<float>::format(),
                             std::move(shape), false));
}

template <typename T>
py::object viewArray(const T* data, std::vector<py::ssize_t> shape, py::handle parent) {
  return asNumpy(ArrayBuffer(nullptr, py::reinterpret_borrow<py::object>(parent),
                             const_cast<T*>(data), sizeof(T), py::format_descriptor<T>::format(),
                             std::move(shape), true));
}

template py::object ownedArray<float>(std::vector<float>&&, std::vector<py::ssize_t>);
template py::object ownedArray<int>(std::vector<int>&&, std::vector<py::ssize_t>);
template py::object ownedArray<double>(std::vector<double>&&, std::vector<py::ssize_t>);
template py::object viewArray<float>(const float*, std::vector<py::ssize_t>, py::handle);
template py::object viewArray<int>(const int*, std::vector<py::ssize_t>, py::handle);

FloatArray::FloatArray(py::handle object, const std::string& what, bool writable) {
  if (PyObject_CheckBuffer(object.ptr()) != 0) {
    try {
      mInfo = py::reinterpret_borrow<py::buffer>(object).request(writable);
    } catch (py::error_already_set& error) {
      DS_THROW(kUsage, what, writable ? " must be a writable array: " : ": ", error.what());
    }
    if (mInfo.itemsize == 4 && isFloat32Format(mInfo.format) && isCContiguous(mInfo)) {
      mObject = py::reinterpret_borrow<py::object>(object);
      return;
    }
    if (writable) {
      DS_THROW(kUsage, what, " must be a writable C-contiguous float32 array; got shape ",
               shapeText(mInfo), " with format '", mInfo.format, "' (itemsize ", mInfo.itemsize,
               isCContiguous(mInfo) ? ")" : ", not C-contiguous)",
               ": pass numpy.empty(shape, dtype=numpy.float32)");
    }
  } else if (writable) {
    DS_THROW(kUsage, what, " must be a writable C-contiguous float32 numpy array, not ",
             std::string(py::str(object.get_type().attr("__name__"))));
  }
  py::module_ numpy = py::module_::import("numpy");
  try {
    mObject = numpy.attr("ascontiguousarray")(object, numpy.attr("float32"));
  } catch (py::error_already_set& error) {
    DS_THROW(kUsage, what, ": cannot read it as a float32 array: ", error.what());
  }
  mInfo = py::reinterpret_borrow<py::buffer>(mObject).request(false);
  mCopied = true;
}

std::string FloatArray::describe() const {
  return shapeText(mInfo) + " float32";
}

FrameBlockShape frameBlockShape(const FloatArray& array, const std::string& what) {
  FrameBlockShape shape;
  if (array.ndim() == 3 && array.dim(2) == 3) {
    shape.frames = static_cast<int>(array.dim(0));
    shape.vertices = static_cast<int>(array.dim(1));
  } else if (array.ndim() == 2 && array.dim(1) == 3) {
    shape.frames = 1;
    shape.vertices = static_cast<int>(array.dim(0));
  } else {
    DS_THROW(kUsage, what, " must be shaped (frames, vertices, 3) or (vertices, 3); got ",
             array.describe());
  }
  return shape;
}

std::vector<int> intVector(py::handle object, const std::string& what) {
  py::module_ numpy = py::module_::import("numpy");
  py::object array;
  try {
    array = numpy.attr("ascontiguousarray")(object, numpy.attr("int32")).attr("reshape")(-1);
  } catch (py::error_already_set& error) {
    DS_THROW(kUsage, what, ": cannot read it as an integer array: ", error.what());
  }
  const py::buffer_info info = py::reinterpret_borrow<py::buffer>(array).request(false);
  std::vector<int> values(static_cast<std::size_t>(info.size));
  if (!values.empty()) {
    std::memcpy(values.data(), info.ptr, values.size() * sizeof(int));
  }
  return values;
}

long long wholeNumber(py::handle object, const std::string& what, long long min, long long max) {
  const std::string shown = py::repr(object);
  const auto outside = [&]() {
    DS_THROW(kUsage, what, " ", shown, " is outside ", min, " to ", max);
  };
  if (PyBool_Check(object.ptr())) {
    DS_THROW(kUsage, what, " must be a whole number, not ", shown);
  }
  if (PyFloat_Check(object.ptr())) {
    const double value = PyFloat_AsDouble(object.ptr());
    if (!std::isfinite(value) || value != std::floor(value)) {
      DS_THROW(kUsage, what, " ", shown, " is not a whole number");
    }
    if (value < static_cast<double>(min) || value > static_cast<double>(max)) {
      outside();
    }
    return static_cast<long long>(value);
  }
  PyObject* index = PyNumber_Index(object.ptr());  // Python ints, numpy integers
  if (index == nullptr) {
    PyErr_Clear();
    DS_THROW(kUsage, what, " must be a whole number, not ",
             std::string(py::str(object.get_type().attr("__name__"))), " ", shown);
  }
  int overflow = 0;
  const long long value = PyLong_AsLongLongAndOverflow(index, &overflow);
  Py_DECREF(index);
  if (overflow != 0 || value < min || value > max) {
    outside();
  }
  return value;
}

int frameNumber(py::handle object, const std::string& what) {
  return static_cast<int>(
      wholeNumber(object, what, std::numeric_limits<int>::min(), std::numeric_limits<int>::max()));
}

std::vector<int> frameList(py::handle object, const std::string& what) {
  if (PyLong_Check(object.ptr()) || PyFloat_Check(object.ptr())) {
    return {frameNumber(object, what)};
  }
  // A sequence, an array or a numpy scalar: numpy's Python values (ints of any size, floats),
  // each checked; numpy's own conversion to int32 would wrap or truncate silently.
  py::list items;
  try {
    items =
        py::module_::import("numpy").attr("asarray")(object).attr("reshape")(-1).attr("tolist")();
  } catch (py::error_already_set& error) {
    DS_THROW(kUsage, what, ": cannot read it as a list of frame numbers: ", error.what());
  }
  std::vector<int> frames;
  frames.reserve(items.size());
  for (py::handle item : items) {
    frames.push_back(frameNumber(item, what + ": frame"));
  }
  return frames;
}

const char* errorKind(ErrorCode code) {
  switch (code) {
    case ErrorCode::kUsage:
      return "usage";
    case ErrorCode::kInput:
      return "input";
    case ErrorCode::kOutput:
      return "output";
    case ErrorCode::kDevice:
      return "device";
    case ErrorCode::kNumerical:
      return "numerical";
    case ErrorCode::kInterrupted:
      return "interrupted";
    case ErrorCode::kInternal:
      break;
  }
  return "internal";
}

bool isPathLike(py::handle object) {
  return py::isinstance<py::str>(object) ||
         py::isinstance(object, py::module_::import("os").attr("PathLike"));
}

std::string pathString(py::handle object) {
  return py::str(py::module_::import("os").attr("fspath")(object));
}

}  // namespace drivenshape::python

PYBIND11_MODULE(_drivenshape, module) {
  namespace ds = drivenshape;
  namespace dp = drivenshape::python;
  using dp::py::arg;
  module.doc() = "drivenshape: data-driven cloth (DrivenShape) evaluated in memory";
  module.attr("__version__") = ds::kVersion;

  dp::py::class_<dp::ArrayBuffer>(module, "_Buffer", dp::py::buffer_protocol(),
                                  "C++ memory shown to numpy without a copy")
      .def_buffer(&dp::ArrayBuffer::info);

  // drivenshape.Error(RuntimeError): the library's drivenshape::Error, message unchanged, with
  // `kind` ("usage", "input", ...) and `code` (the command line's exit code). Never freed: the
  // translator may run until the interpreter exits.
  static auto* errorType = new dp::py::exception<ds::Error>(module, "Error", PyExc_RuntimeError);
  errorType->doc() =
      "An error of the drivenshape library. `kind` says what failed ('usage', 'input', "
      "'output', 'device', 'numerical', 'interrupted', 'internal'); `code` is the matching exit "
      "code of the command line (2 usage, 3 input, 4 output, 5 device, 6 numerical).";
  errorType->attr("kind") = "internal";
  errorType->attr("code") = 1;
  dp::py::register_exception_translator([](std::exception_ptr pointer) {
    try {
      if (pointer) {
        std::rethrow_exception(pointer);
      }
    } catch (const ds::Error& error) {
      const auto type = dp::py::reinterpret_borrow<dp::py::object>(errorType->ptr());
      // Escaped: a message may quote a bad input's raw bytes, which are not UTF-8.
      dp::py::object instance = type(ds::printableText(error.what()));
      instance.attr("kind") = dp::errorKind(error.code());
      instance.attr("code") = static_cast<int>(error.code());
      PyErr_SetObject(errorType->ptr(), instance.ptr());
    }
  });

  dp::bindMeshes(module);
  dp::bindPointCaches(module);
  dp::bindDatabase(module);
  dp::bindEvaluator(module);

  // The shot planner (bind_shot_plan.cpp): plan_shot, BatchPlan, PlaybackPlanner.
  dp::bindShotPlan(module);
  // Simulating what the verdict flags (bind_evaluator.cpp): plan_simulation, splice.
  dp::bindSimulation(module);
}
