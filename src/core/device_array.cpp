// SPDX-License-Identifier: Apache-2.0
// DeviceArray: a host copy and an optional device copy, each marked current or stale.

#include "device_array.h"

#include <atomic>
#include <utility>

#include <drivenshape/error.h>

namespace drivenshape {
namespace {

/// DeviceArray::version(): one counter for every array, so no two arrays share a version.
std::uint64_t nextVersion() {
  static std::atomic<std::uint64_t> counter{0};
  return ++counter;
}

}  // namespace

DeviceArray::DeviceArray(std::unique_ptr<DeviceStorage> storage)
    : mStorage(std::move(storage)), mVersion(nextVersion()) {}
DeviceArray::~DeviceArray() = default;

DeviceArray::DeviceArray(DeviceArray&& other) noexcept
    : mStorage(std::move(other.mStorage)),
      mOwn(std::move(other.mOwn)),
      mView(std::exchange(other.mView, nullptr)),
      mReadOnly(other.mReadOnly),
      mBytes(std::exchange(other.mBytes, 0)),
      mHostCurrent(other.mHostCurrent),
      mDeviceCurrent(other.mDeviceCurrent),
      mVersion(std::exchange(other.mVersion, nextVersion())) {}

DeviceArray& DeviceArray::operator=(DeviceArray&& other) noexcept {
  mStorage = std::move(other.mStorage);
  mOwn = std::move(other.mOwn);
  mView = std::exchange(other.mView, nullptr);
  mReadOnly = other.mReadOnly;
  mBytes = std::exchange(other.mBytes, 0);
  mHostCurrent = other.mHostCurrent;
  mDeviceCurrent = other.mDeviceCurrent;
  mVersion = std::exchange(other.mVersion, nextVersion());
  return *this;
}

void DeviceArray::resizeBytes(std::size_t bytes) {
  mView = nullptr;
  mReadOnly = false;
  if (mOwn.size() < bytes) {
    mOwn.resize(bytes);
  }
  mBytes = bytes;
  mVersion = nextVersion();
  // Nothing holds values yet: whichever side writes first becomes current.
  mHostCurrent = true;
  mDeviceCurrent = false;
}

void DeviceArray::viewBytes(void* data, std::size_t bytes, bool readOnly) {
  mView = data;
  mReadOnly = readOnly;
  mBytes = bytes;
  mVersion = nextVersion();
  mHostCurrent = true;
  mDeviceCurrent = false;
}

const void* DeviceArray::hostData() const {
  return mView != nullptr ? mView : mOwn.data();
}

void* DeviceArray::hostMutable() {
  if (mReadOnly) {
    DS_THROW(kInternal, "a read-only array view was written on the host");
  }
  return mView != nullptr ? mView : mOwn.data();
}

const void* DeviceArray::hostForRead() {
  if (!mHostCurrent) {
    // Only a read-only view can be stale while current on the device, and views start current.
    mStorage->download(mView != nullptr ? mView : mOwn.data(), mBytes);
    mHostCurrent = true;
  }
  return hostData();
}

void* DeviceArray::hostForWrite(bool keep) {
  if (keep) {
    hostForRead();
  }
  void* data = hostMutable();
  mVersion = nextVersion();
  mHostCurrent = true;
  mDeviceCurrent = false;
  return data;
}

DeviceStorage* DeviceArray::deviceForRead() {
  if (mStorage == nullptr) {
    return nullptr;
  }
  if (!mDeviceCurrent) {
    mStorage->reserve(mBytes);
    if (mHostCurrent && mBytes > 0) {
      mStorage->upload(hostData(), mBytes);
    }
    mDeviceCurrent = true;
  }
  return mStorage.get();
}

DeviceStorage* DeviceArray::deviceForWrite() {
  if (mStorage == nullptr) {
    return nullptr;
  }
  if (mReadOnly) {
    DS_THROW(kInternal, "a read-only array view was written on the device");
  }
  mStorage->reserve(mBytes);
  mVersion = nextVersion();
  mDeviceCurrent = true;
  mHostCurrent = false;
  return mStorage.get();
}

DeviceStorage* DeviceArray::deviceForModify() {
  DeviceStorage* storage = deviceForRead();
  if (storage != nullptr) {
    if (mReadOnly) {
      DS_THROW(kInternal, "a read-only array view was written on the device");
    }
    mVersion = nextVersion();
    mHostCurrent = false;
  }
  return storage;
}

}  // namespace drivenshape
