// SPDX-License-Identifier: Apache-2.0
// DeviceArray: a host copy and an optional device copy, each marked current or stale.

#include <drivenshape/device_array.h>

#include <drivenshape/error.h>

namespace drivenshape {

DeviceArray::DeviceArray(std::unique_ptr<DeviceStorage> storage) : mStorage(std::move(storage)) {}
DeviceArray::~DeviceArray() = default;
DeviceArray::DeviceArray(DeviceArray&&) noexcept = default;
DeviceArray& DeviceArray::operator=(DeviceArray&&) noexcept = default;

void DeviceArray::resizeBytes(std::size_t bytes) {
  mView = nullptr;
  mReadOnly = false;
  if (mOwn.size() < bytes) {
    mOwn.resize(bytes);
  }
  mBytes = bytes;
  // Nothing holds values yet: whichever side writes first becomes current.
  mHostCurrent = true;
  mDeviceCurrent = false;
}

void DeviceArray::viewBytes(void* data, std::size_t bytes, bool readOnly) {
  mView = data;
  mReadOnly = readOnly;
  mBytes = bytes;
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
    mHostCurrent = false;
  }
  return storage;
}

}  // namespace drivenshape
