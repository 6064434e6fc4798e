// SPDX-License-Identifier: Apache-2.0
#include "test_support.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>

#include <drivenshape/database_build.h>
#include <drivenshape/mesh.h>
#include <drivenshape/point_cache.h>

namespace drivenshape::testing {
namespace {

struct ClState {
  cl::Context context;
  cl::Device device;
  cl::CommandQueue queue;
};

std::optional<ClState>& clState() {
  static std::optional<ClState> state;
  return state;
}

std::string& clFailure() {
  static std::string failure;
  return failure;
}

}  // namespace

std::uint32_t testSeed(std::uint32_t fallback) {
  std::uint32_t seed = fallback;
  if (const char* text = std::getenv("DS_SEED")) {
    seed = static_cast<std::uint32_t>(std::strtoul(text, nullptr, 10));
  }
  static bool printed = false;
  if (!printed) {
    std::printf("[ seed     ] %u (override with DS_SEED=N)\n", seed);
    printed = true;
  }
  return seed;
}

std::string dataDir() {
  return DS_TEST_DATA_DIR;
}

Database buildSleeveDatabase(bool poseModel, int count) {
  const std::string sleeve = dataDir() + "/sleeve/";
  const Mesh driver = readObj(sleeve + "driver_rest.obj");
  const Mesh driven = readObj(sleeve + "driven_rest.obj");
  const auto driverCache = openPointCache(sleeve + "train.driver.pc2");
  const auto drivenCache = openPointCache(sleeve + "train.driven.pc2");
  DatabaseBuildOptions options;
  options.count = count;
  options.poseModel = poseModel;
  return buildDatabase(driver, driven, *driverCache, *drivenCache, options);
}

TempDir::TempDir() {
  static std::atomic<int> counter{0};
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = info != nullptr ? std::string(info->test_suite_name()) + "." + info->name()
                                     : std::string("test");
  for (char& ch : name) {
    if (ch == '/') {
      ch = '_';
    }
  }
  mPath = std::string(DS_BINARY_DIR) + "/test-tmp/" + name + "-" + std::to_string(::getpid()) +
          "-" + std::to_string(counter++);
  std::filesystem::remove_all(mPath);
  std::filesystem::create_directories(mPath);
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::permissions(mPath, std::filesystem::perms::owner_all,
                               std::filesystem::perm_options::add, ec);
  std::filesystem::remove_all(mPath, ec);
}

void expectThrows(const std::function<void()>& call, ErrorCode code, const std::string& fragment) {
  try {
    call();
    ADD_FAILURE() << "no exception; expected a drivenshape::Error mentioning '" << fragment << "'";
  } catch (const Error& error) {
    EXPECT_EQ(static_cast<int>(error.code()), static_cast<int>(code)) << error.what();
    EXPECT_NE(std::string(error.what()).find(fragment), std::string::npos)
        << "'" << fragment << "' not found in: " << error.what();
  }
}

void OpenClTest::SetUpTestSuite() {
  if (clState() || !clFailure().empty()) {
    return;
  }
  try {
    std::vector<cl::Platform> platforms;
    cl::Platform::get(&platforms);
    const char* wanted = std::getenv("DS_TEST_DEVICE");
    for (auto& platform : platforms) {
      std::vector<cl::Device> devices;
      platform.getDevices(CL_DEVICE_TYPE_ALL, &devices);
      for (auto& device : devices) {
        const std::string name = device.getInfo<CL_DEVICE_NAME>();
        if (wanted != nullptr && name.find(wanted) == std::string::npos) {
          continue;
        }
        cl::Context context(device);
        cl::CommandQueue queue(context, device);
        clState() = ClState{context, device, queue};
        std::printf("[ device   ] %s / %s (%s)\n", platform.getInfo<CL_PLATFORM_NAME>().c_str(),
                    name.c_str(), device.getInfo<CL_DEVICE_VERSION>().c_str());
        return;
      }
    }
    clFailure() = "no OpenCL device found (is pocl-opencl-icd installed?)";
  } catch (const cl::Error& error) {
    clFailure() = std::string("OpenCL error while looking for a device: ") + error.what() + " (" +
                  std::to_string(error.err()) + ")";
  }
}

void OpenClTest::SetUp() {
  ASSERT_TRUE(clState().has_value()) << clFailure();
}

cl::Context& OpenClTest::context() {
  return clState()->context;
}
cl::Device& OpenClTest::device() {
  return clState()->device;
}
cl::CommandQueue& OpenClTest::queue() {
  return clState()->queue;
}
std::string OpenClTest::deviceSpec() {
  return clState() ? clState()->device.getInfo<CL_DEVICE_NAME>() : std::string("cpu");
}

std::vector<int> frameRange(int first, int last) {
  std::vector<int> out;
  for (int f = first; f <= last; ++f) {
    out.push_back(f);
  }
  return out;
}

double meanVertexDistance(const std::vector<float>& a, const std::vector<float>& b) {
  double sum = 0.0;
  for (std::size_t i = 0; i + 2 < a.size(); i += 3) {
    const double dx = double(a[i]) - b[i], dy = double(a[i + 1]) - b[i + 1],
                 dz = double(a[i + 2]) - b[i + 2];
    sum += std::sqrt(dx * dx + dy * dy + dz * dz);
  }
  return a.empty() ? 0.0 : sum / static_cast<double>(a.size() / 3);
}

std::vector<double> countedRanks(const std::vector<double>& v) {
  std::vector<double> ranks;
  for (double a : v) {
    int below = 0, equal = 0;
    for (double b : v) {
      below += b < a ? 1 : 0;
      equal += b == a ? 1 : 0;
    }
    ranks.push_back(1.0 + below + 0.5 * (equal - 1));
  }
  return ranks;
}

double referencePearson(const std::vector<double>& x, const std::vector<double>& y) {
  auto constant = [](const std::vector<double>& v) {
    return std::all_of(v.begin(), v.end(), [&](double a) { return a == v[0]; });
  };
  if (constant(x) || constant(y)) {
    return std::nan("");
  }
  double mx = 0.0, my = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    mx += x[i] / static_cast<double>(x.size());
    my += y[i] / static_cast<double>(y.size());
  }
  double sxy = 0.0, sxx = 0.0, syy = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
  }
  return sxy / std::sqrt(sxx * syy);
}

double referenceSpearman(const std::vector<double>& x, const std::vector<double>& y) {
  return referencePearson(countedRanks(x), countedRanks(y));
}

}  // namespace drivenshape::testing
