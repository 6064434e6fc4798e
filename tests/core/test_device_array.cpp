// SPDX-License-Identifier: Apache-2.0
// DeviceArray on a real OpenCL device (PoCL in CI) and on the host device: which copy is
// current after each access, and exactly which accesses copy (counted by the device).

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <memory>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include <drivenshape/device.h>
#include <drivenshape/device_cl.h>
#include <drivenshape/error.h>

#include "device_array.h"

#include "test_support.h"

namespace drivenshape {
namespace {

class DeviceArrayTest : public testing::OpenClTest {
 protected:
  void SetUp() override {
    testing::OpenClTest::SetUp();
    mDevice = makeOpenClDevice(context(), device(), queue());
  }
  /// Copies since the last call: (uploads, downloads).
  std::pair<std::int64_t, std::int64_t> copies() {
    const TransferCounts now = mDevice->transfers();
    const auto result =
        std::make_pair(now.uploads - mSeen.uploads, now.downloads - mSeen.downloads);
    mSeen = now;
    return result;
  }
  std::unique_ptr<Device> mDevice;
  TransferCounts mSeen;
};

TEST_F(DeviceArrayTest, CopiesOnlyWhenTheOtherSideIsStale) {
  DeviceArray array = mDevice->makeArray();
  ASSERT_NE(array.storage(), nullptr);
  array.resize<float>(1000);
  float* host = array.write<float>();
  for (int i = 0; i < 1000; ++i) {
    host[i] = static_cast<float>(i) * 0.5f;
  }
  copies();
  array.deviceForRead();
  EXPECT_EQ(copies(), std::make_pair(std::int64_t{1}, std::int64_t{0}));
  array.deviceForRead();  // current on both sides: nothing moves
  array.read<float>();
  EXPECT_EQ(copies(), std::make_pair(std::int64_t{0}, std::int64_t{0}));

  // Written on the device: the host copy is stale until read, then read back once.
  std::vector<float> other(1000, 7.0f);
  array.deviceForWrite()->upload(other.data(), other.size() * sizeof(float));
  copies();
  EXPECT_EQ(array.hostIfCurrent<float>(), nullptr);
  EXPECT_EQ(array.read<float>()[999], 7.0f);
  EXPECT_EQ(array.read<float>()[0], 7.0f);
  EXPECT_EQ(copies(), std::make_pair(std::int64_t{0}, std::int64_t{1}));

  // write() never downloads, modify() does when the device is newer.
  array.deviceForWrite();
  array.write<float>()[0] = 1.0f;
  EXPECT_EQ(copies(), std::make_pair(std::int64_t{0}, std::int64_t{0}));
  array.deviceForModify();
  EXPECT_EQ(copies(), std::make_pair(std::int64_t{1}, std::int64_t{0}));
  array.modify<float>();
  EXPECT_EQ(copies(), std::make_pair(std::int64_t{0}, std::int64_t{1}));
}

TEST_F(DeviceArrayTest, ViewsUseTheCallersMemory) {
  std::vector<float> caller(300, 2.0f);
  DeviceArray array = mDevice->makeArray();
  array.view(caller.data(), caller.size());
  EXPECT_EQ(array.read<float>(), caller.data());
  std::vector<float> fresh(300, 9.0f);
  array.deviceForWrite()->upload(fresh.data(), fresh.size() * sizeof(float));
  copies();
  array.read<float>();  // downloads straight into the caller's memory
  EXPECT_EQ(caller[123], 9.0f);
  EXPECT_EQ(copies(), std::make_pair(std::int64_t{0}, std::int64_t{1}));

  const std::vector<float> constant(30, 1.0f);
  DeviceArray readOnly = mDevice->makeArray();
  readOnly.view(constant.data(), constant.size());
  EXPECT_THROW(readOnly.write<float>(), Error);
  EXPECT_THROW(readOnly.deviceForWrite(), Error);
  EXPECT_NE(readOnly.deviceForRead(), nullptr);
}

TEST_F(DeviceArrayTest, TheVersionChangesExactlyWhenTheValuesMay) {
  DeviceArray array = mDevice->makeArray();
  DeviceArray other = mDevice->makeArray();
  EXPECT_NE(array.version(), other.version());
  std::vector<std::uint64_t> seen{array.version(), other.version()};
  const auto changed = [&](const char* what) {
    SCOPED_TRACE(what);
    EXPECT_EQ(std::count(seen.begin(), seen.end(), array.version()), 0);
    seen.push_back(array.version());
  };
  array.resize<int>(8);
  changed("resize");
  array.write<int>()[0] = 1;
  changed("write");
  const std::uint64_t written = array.version();
  array.read<int>();
  array.deviceForRead();
  EXPECT_EQ(array.version(), written) << "reads and uploads keep the version";
  array.deviceForModify();
  changed("deviceForModify");
  array.read<int>();
  EXPECT_EQ(array.version(), seen.back()) << "a download keeps the version";
  array.modify<int>()[1] = 2;
  changed("modify");
  array.deviceForWrite();
  changed("deviceForWrite");
  std::vector<int> memory(8, 3);
  array.view(memory.data(), memory.size());
  changed("view");
  DeviceArray moved = std::move(array);
  EXPECT_EQ(moved.version(), seen.back()) << "a move carries the version";
  changed("the moved-from array");
}

TEST_F(DeviceArrayTest, HostDeviceArraysHaveNoDeviceSide) {
  std::unique_ptr<Device> host = makeHostDevice();
  DeviceArray array = host->makeArray();
  array.resize<int>(10);
  array.write<int>()[3] = 42;
  EXPECT_EQ(array.deviceForRead(), nullptr);
  EXPECT_EQ(array.deviceForWrite(), nullptr);
  EXPECT_EQ(array.read<int>()[3], 42);
  EXPECT_EQ(array.size<int>(), 10u);
}

}  // namespace
}  // namespace drivenshape
