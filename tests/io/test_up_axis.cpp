// SPDX-License-Identifier: Apache-2.0
// Tests for src/io/up_axis.cpp: the Z-up <-> Y-up rotation the exporters use is exact, bit for
// bit, on every kind of float (signed zeros, denormals, infinities, NaN payloads), and the flag
// parser names the flag it was given.

#include "up_axis.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "io_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

std::uint32_t bitsOf(float value) {
  std::uint32_t bits;
  std::memcpy(&bits, &value, 4);
  return bits;
}

/// The expected result, built on the bit patterns (a sign flip is bit 31), not with the
/// arithmetic the code under test uses: Z up -> Y up is (x, y, z) -> (x, z, -y).
std::vector<std::uint32_t> expectedZToY(const std::vector<float>& xyz) {
  std::vector<std::uint32_t> out(xyz.size());
  for (std::size_t i = 0; i < xyz.size(); i += 3) {
    out[i] = bitsOf(xyz[i]);
    out[i + 1] = bitsOf(xyz[i + 2]);
    out[i + 2] = bitsOf(xyz[i + 1]) ^ 0x80000000u;
  }
  return out;
}

/// Random finite values over many magnitudes, then the special ones.
std::vector<float> testPoints() {
  std::mt19937 random(testSeed());
  std::uniform_real_distribution<float> mantissa(-2.0f, 2.0f);
  std::uniform_int_distribution<int> exponent(-40, 40);
  std::vector<float> xyz;
  for (int i = 0; i < 3000; ++i) {
    xyz.push_back(std::ldexp(mantissa(random), exponent(random)));
  }
  const float specials[] = {0.0f,
                            -0.0f,
                            1.0e-42f,
                            -1.0e-42f,
                            std::numeric_limits<float>::min(),
                            std::numeric_limits<float>::max(),
                            -std::numeric_limits<float>::max(),
                            std::numeric_limits<float>::infinity(),
                            -std::numeric_limits<float>::infinity(),
                            std::numeric_limits<float>::quiet_NaN()};
  for (float a : specials) {
    for (float b : specials) {
      xyz.insert(xyz.end(), {a, b, a});
      xyz.insert(xyz.end(), {b, a, b});
    }
  }
  return xyz;
}

void expectBits(const std::vector<float>& got, const std::vector<std::uint32_t>& expected,
                const char* what) {
  ASSERT_EQ(got.size(), expected.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(bitsOf(got[i]), expected[i]) << what << ": float " << i << " (point " << i / 3
                                           << ", axis " << i % 3 << "); tolerance: bitwise";
  }
}

TEST(UpAxis, ZToYIsTheRotationBitForBit) {
  const std::vector<float> source = testPoints();
  std::vector<float> xyz = source;
  convertUpAxis(xyz.data(), xyz.size() / 3, UpAxis::kZ, UpAxis::kY);
  expectBits(xyz, expectedZToY(source), "Z -> Y");

  // A right-handed rotation: +Z (up) goes to +Y (up), +Y (forward in Blender) to -Z.
  std::vector<float> axes = {0, 0, 1, 0, 1, 0, 1, 0, 0};
  convertUpAxis(axes.data(), 3, UpAxis::kZ, UpAxis::kY);
  EXPECT_EQ(axes, (std::vector<float>{0, 1, 0, 0, 0, -1, 1, 0, 0}));
}

TEST(UpAxis, YToZIsTheInverseAndTheRoundTripKeepsEveryBit) {
  const std::vector<float> source = testPoints();
  std::vector<float> xyz = source;
  convertUpAxis(xyz.data(), xyz.size() / 3, UpAxis::kY, UpAxis::kZ);
  // Y up -> Z up is (x, y, z) -> (x, -z, y).
  std::vector<std::uint32_t> expected(source.size());
  for (std::size_t i = 0; i < source.size(); i += 3) {
    expected[i] = bitsOf(source[i]);
    expected[i + 1] = bitsOf(source[i + 2]) ^ 0x80000000u;
    expected[i + 2] = bitsOf(source[i + 1]);
  }
  expectBits(xyz, expected, "Y -> Z");

  convertUpAxis(xyz.data(), xyz.size() / 3, UpAxis::kZ, UpAxis::kY);
  std::vector<std::uint32_t> original(source.size());
  for (std::size_t i = 0; i < source.size(); ++i) {
    original[i] = bitsOf(source[i]);
  }
  expectBits(xyz, original, "Y -> Z -> Y");
}

TEST(UpAxis, SameAxisChangesNothing) {
  const std::vector<float> source = testPoints();
  std::vector<float> xyz = source;
  convertUpAxis(xyz.data(), xyz.size() / 3, UpAxis::kZ, UpAxis::kZ);
  convertUpAxis(xyz.data(), xyz.size() / 3, UpAxis::kY, UpAxis::kY);
  EXPECT_EQ(std::memcmp(xyz.data(), source.data(), 4 * xyz.size()), 0);
  convertUpAxis(nullptr, 0, UpAxis::kZ, UpAxis::kY);  // nothing to do, nothing touched
}

TEST(UpAxis, ParseNamesTheFlagAndTheValue) {
  EXPECT_EQ(parseUpAxis("Y", "--up-axis"), UpAxis::kY);
  EXPECT_EQ(parseUpAxis("Z", "--up-axis"), UpAxis::kZ);
  EXPECT_STREQ(upAxisName(UpAxis::kY), "Y");
  EXPECT_STREQ(upAxisName(UpAxis::kZ), "Z");
  for (const char* bad : {"X", "y", "", "-Z", "Z up"}) {
    const Error error = catchError([&] { parseUpAxis(bad, "--up-axis"); });
    EXPECT_EQ(error.code(), ErrorCode::kUsage) << bad;
    EXPECT_TRUE(contains(error.what(), std::string("--up-axis '") + bad + "'"));
    EXPECT_TRUE(contains(error.what(), "Z")) << error.what();
  }
}

}  // namespace
}  // namespace drivenshape::testing
