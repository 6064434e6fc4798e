// SPDX-License-Identifier: Apache-2.0
#pragma once

// Arrays that the backends of one Device hand to each other. A DeviceArray has a host copy and,
// on an OpenCL device, a device copy; it remembers which copy is current and copies across only
// when the other side asks for it and its copy is stale (a mirrored buffer). The evaluator keeps
// a block of frames in such arrays from the projection to the last kernel, so that an OpenCL
// device reads the shot's driver in once and gives the cloth back once; on the host device the
// device side does not exist and every access is a plain pointer.
//
//   DeviceArray cloth = device.makeArray();
//   cloth.resize<float>(frames * 3 * Vd);
//   closest.rebuild(frames, restHits, driver, local, cloth);  // written on the device
//   const float* xyz = cloth.read<float>();                  // one download, here

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace drivenshape {

/// The device side of a DeviceArray: device memory on one OpenCL context. Backends of the
/// same device reach the memory through their own downcast (the OpenCL one is private to the
/// library); every other caller only moves bytes.
class DeviceStorage {
 public:
  virtual ~DeviceStorage() = default;
  /// Makes room for at least `bytes`; the contents need not survive a growth.
  virtual void reserve(std::size_t bytes) = 0;
  /// Copies `bytes` from host memory into the start of the device memory (blocking).
  virtual void upload(const void* host, std::size_t bytes) = 0;
  /// Copies the first `bytes` of the device memory to host memory (blocking).
  virtual void download(void* host, std::size_t bytes) = 0;
};

/// A block of plain values (floats, ints, SurfaceHits) with a host copy and, when its device
/// has one, a device copy. Sizes are in bytes inside and in elements of T at the accessors.
/// Not thread-safe; it belongs to one backend user (an Evaluator) like the backends themselves.
class DeviceArray {
 public:
  /// A host-only array (the host device), or one with `storage` as its device side.
  explicit DeviceArray(std::unique_ptr<DeviceStorage> storage = nullptr);
  ~DeviceArray();
  DeviceArray(DeviceArray&&) noexcept;
  DeviceArray& operator=(DeviceArray&&) noexcept;
  DeviceArray(const DeviceArray&) = delete;
  DeviceArray& operator=(const DeviceArray&) = delete;

  /// Holds `count` elements of T in the array's own host memory; the contents are undefined
  /// until written (on either side).
  template <typename T>
  void resize(std::size_t count) {
    resizeBytes(count * sizeof(T));
  }
  /// Makes caller memory the host copy: `count` elements of T, current; the device copy (if
  /// any) is stale. The memory must stay valid while the array uses it. A read-only view
  /// refuses write() and modify().
  template <typename T>
  void view(const T* data, std::size_t count) {
    viewBytes(const_cast<T*>(data), count * sizeof(T), true);
  }
  template <typename T>
  void view(T* data, std::size_t count) {
    viewBytes(data, count * sizeof(T), false);
  }

  template <typename T>
  std::size_t size() const {
    return mBytes / sizeof(T);
  }
  std::size_t bytes() const { return mBytes; }

  /// The host copy, brought up to date first (one download when the device copy is newer).
  template <typename T>
  const T* read() {
    return static_cast<const T*>(hostForRead());
  }
  /// The host copy for the caller to overwrite entirely: nothing is downloaded, and the
  /// device copy becomes stale.
  template <typename T>
  T* write() {
    return static_cast<T*>(hostForWrite(false));
  }
  /// The host copy, up to date, for the caller to change in place: the device copy becomes
  /// stale.
  template <typename T>
  T* modify() {
    return static_cast<T*>(hostForWrite(true));
  }
  /// The host copy if it is current, else null (never copies).
  template <typename T>
  const T* hostIfCurrent() const {
    return mHostCurrent ? static_cast<const T*>(hostData()) : nullptr;
  }

  // The device side, for the backends of the device that made the array (null on the host
  // device or for an array of another device's kind).
  /// Device memory holding the current values (one upload when the host copy is newer).
  DeviceStorage* deviceForRead();
  /// Device memory the caller overwrites entirely: the host copy becomes stale.
  DeviceStorage* deviceForWrite();
  /// Device memory, current, that the caller changes in place: the host copy becomes stale.
  DeviceStorage* deviceForModify();
  DeviceStorage* storage() { return mStorage.get(); }

  /// A number that changes whenever the values may change: on resize(), view(), write(),
  /// modify(), deviceForWrite() and deviceForModify(). Unique across arrays, never 0: two calls
  /// that see the same version see the same values, so a backend may keep what it derived from
  /// them (the OpenCL closest-point search keeps the refitted tree of a pose block).
  std::uint64_t version() const { return mVersion; }

 private:
  void resizeBytes(std::size_t bytes);
  void viewBytes(void* data, std::size_t bytes, bool readOnly);
  const void* hostData() const;
  void* hostMutable();
  const void* hostForRead();
  void* hostForWrite(bool keep);

  std::unique_ptr<DeviceStorage> mStorage;
  std::vector<unsigned char> mOwn;  ///< the host copy when it is not a view
  void* mView = nullptr;            ///< caller memory (view()), or null
  bool mReadOnly = false;
  std::size_t mBytes = 0;
  bool mHostCurrent = true;
  bool mDeviceCurrent = false;
  std::uint64_t mVersion;
};

}  // namespace drivenshape
