// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/frames.h>

#include <algorithm>
#include <random>

#include "io_test_util.h"
#include "test_support.h"

namespace drivenshape::testing {
namespace {

std::vector<int> span(int first, int last, int step = 1) {
  std::vector<int> frames;
  for (int f = first; f <= last; f += step) {
    frames.push_back(f);
  }
  return frames;
}

TEST(FrameRange, SingleFrame) {
  EXPECT_EQ(parseFrameRange("1001"), std::vector<int>{1001});
}

TEST(FrameRange, InclusiveRange) {
  const std::vector<int> frames = parseFrameRange("1001-1100");
  ASSERT_EQ(frames.size(), 100u);
  EXPECT_EQ(frames.front(), 1001);
  EXPECT_EQ(frames.back(), 1100);
  EXPECT_EQ(frames, span(1001, 1100));
}

TEST(FrameRange, SteppedRange) {
  EXPECT_EQ(parseFrameRange("1001-1100x2"), span(1001, 1099, 2));
  EXPECT_EQ(parseFrameRange("1-10x4"), (std::vector<int>{1, 5, 9}));
  EXPECT_EQ(parseFrameRange("7-7x3"), (std::vector<int>{7}));
}

TEST(FrameRange, ListKeepsOrderAndDropsDuplicates) {
  std::vector<int> expected = {1001, 1005};
  const std::vector<int> tail = span(1010, 1020);
  expected.insert(expected.end(), tail.begin(), tail.end());
  EXPECT_EQ(parseFrameRange("1001,1005,1010-1020"), expected);
  EXPECT_EQ(parseFrameRange("20,3-5,4,1"), (std::vector<int>{20, 3, 4, 5, 1}));
  EXPECT_EQ(parseFrameRange(" 1 , 2 "), (std::vector<int>{1, 2}));
}

TEST(FrameRange, NegativeFrames) {
  EXPECT_EQ(parseFrameRange("-5--1"), (std::vector<int>{-5, -4, -3, -2, -1}));
  EXPECT_EQ(parseFrameRange("-3-2"), (std::vector<int>{-3, -2, -1, 0, 1, 2}));
  EXPECT_EQ(parseFrameRange("-10--1x3"), (std::vector<int>{-10, -7, -4, -1}));
  EXPECT_EQ(parseFrameRange("-7"), (std::vector<int>{-7}));
}

void expectUsageError(const std::string& text, const std::string& part) {
  SCOPED_TRACE(text);
  const Error error = catchError([&] { parseFrameRange(text); });
  EXPECT_EQ(error.code(), ErrorCode::kUsage);
  EXPECT_TRUE(contains(error.what(), part));
}

TEST(FrameRange, BackwardsRangeSaysHowToWriteIt) {
  expectUsageError("1100-1001", "frame range '1100-1001' runs backwards; write 1001-1100");
  expectUsageError("1100-1001x2", "write 1001-1100x2");
  expectUsageError("1,1100-1001", "'1,1100-1001'");
}

TEST(FrameRange, MalformedTextIsAUsageError) {
  expectUsageError("", "empty");
  expectUsageError("   ", "empty");
  expectUsageError("abc", "'abc'");
  expectUsageError("1001-", "'1001-'");
  expectUsageError("1001-1100x", "'1001-1100x'");
  expectUsageError("1001-1100x0", "step");
  expectUsageError("1001-1100x-2", "step");
  expectUsageError("1001:1100", "'1001:1100'");
  expectUsageError("1001,,1003", "'1001,,1003'");
  expectUsageError("1001,", "'1001,'");
  expectUsageError("10.5", "'10.5'");
  expectUsageError("99999999999", "99999999999");
  expectUsageError("1-1100000000", "more than");
}

TEST(FrameRange, FormatCompactsRuns) {
  EXPECT_EQ(formatFrameRange(span(1001, 1100)), "1001-1100");
  EXPECT_EQ(formatFrameRange({1, 3, 5, 7, 9, 20}), "1-9x2,20");
  EXPECT_EQ(formatFrameRange({1001}), "1001");
  EXPECT_EQ(formatFrameRange({1, 5}), "1,5");
  EXPECT_EQ(formatFrameRange({1, 2}), "1-2");
  EXPECT_EQ(formatFrameRange({-5, -4, -3}), "-5--3");
  EXPECT_EQ(formatFrameRange({5, 4, 3}), "5,4,3");
  EXPECT_EQ(formatFrameRange({}), "");
}

TEST(FrameRange, FormatThenParseGivesTheFramesBack) {
  std::mt19937 random(testSeed());
  std::uniform_int_distribution<int> frame(-50, 300);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<int> frames;
    for (int i = 0; i < 1 + trial % 40; ++i) {
      frames.push_back(frame(random));
    }
    if (trial % 2 == 0) {
      std::sort(frames.begin(), frames.end());
    }
    std::vector<int> unique;
    for (int f : frames) {
      if (std::find(unique.begin(), unique.end(), f) == unique.end()) {
        unique.push_back(f);
      }
    }
    const std::string text = formatFrameRange(unique);
    EXPECT_EQ(parseFrameRange(text), unique) << text;
  }
}

TEST(FramePattern, Detection) {
  EXPECT_TRUE(hasFramePattern("cloth.####.exr"));
  EXPECT_TRUE(hasFramePattern("cloth.#.exr"));
  EXPECT_TRUE(hasFramePattern("cloth.%04d.exr"));
  EXPECT_TRUE(hasFramePattern("cloth.%d.exr"));
  EXPECT_TRUE(hasFramePattern("cloth.$F4.exr"));
  EXPECT_TRUE(hasFramePattern("cloth.$F.exr"));
  EXPECT_FALSE(hasFramePattern("cloth.1001.exr"));
  EXPECT_FALSE(hasFramePattern("cloth.pc2"));
  EXPECT_FALSE(hasFramePattern("100%.exr"));
  EXPECT_FALSE(hasFramePattern("$HOME/cloth.exr"));
}

TEST(FramePattern, Expansion) {
  EXPECT_EQ(expandFramePattern("out/cloth.####.exr", 7), "out/cloth.0007.exr");
  EXPECT_EQ(expandFramePattern("cloth.####.exr", 1001), "cloth.1001.exr");
  EXPECT_EQ(expandFramePattern("cloth.####.exr", 12345), "cloth.12345.exr");
  EXPECT_EQ(expandFramePattern("cloth.##.exr", 5), "cloth.05.exr");
  EXPECT_EQ(expandFramePattern("cloth.####.exr", -12), "cloth.-0012.exr");
  EXPECT_EQ(expandFramePattern("cloth.%04d.exr", 42), "cloth.0042.exr");
  EXPECT_EQ(expandFramePattern("cloth.%d.exr", 42), "cloth.42.exr");
  EXPECT_EQ(expandFramePattern("cloth.%06d.exr", -3), "cloth.-000003.exr");
  EXPECT_EQ(expandFramePattern("cloth.$F4.exr", 42), "cloth.0042.exr");
  EXPECT_EQ(expandFramePattern("cloth.$F.exr", 42), "cloth.42.exr");
  EXPECT_EQ(expandFramePattern("cloth.$F.exr", 1001), "cloth.1001.exr");
}

TEST(FramePattern, NoTokenOrTwoTokensIsAUsageError) {
  Error error = catchError([] { expandFramePattern("cloth.exr", 1); });
  EXPECT_EQ(error.code(), ErrorCode::kUsage);
  EXPECT_TRUE(contains(error.what(), "cloth.exr"));
  error = catchError([] { expandFramePattern("shot_####/cloth.%04d.exr", 1); });
  EXPECT_EQ(error.code(), ErrorCode::kUsage);
  EXPECT_TRUE(contains(error.what(), "2 frame tokens"));
}

TEST(Frames, SequenceStemIsTheNameBeforeTheToken) {
  EXPECT_EQ(framePatternPosition("cloth.####.exr"), 6u);
  EXPECT_EQ(framePatternPosition("a%b/cloth_$F4.exr"), 10u);  // a '%' that is no token
  EXPECT_EQ(framePatternPosition("cloth.exr"), std::string::npos);
  EXPECT_EQ(sequenceStem("out/cloth.####.exr"), "cloth");
  EXPECT_EQ(sequenceStem("/a/b/shot_010_%04d.exr"), "shot_010");
  EXPECT_EQ(sequenceStem("out/####.exr"), "bake");
  EXPECT_EQ(sequenceStem("100%/cloth-$F.exr"), "cloth");
}

}  // namespace
}  // namespace drivenshape::testing
