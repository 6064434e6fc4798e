// SPDX-License-Identifier: Apache-2.0
// How every writer creates its file (AtomicFile: exclusive, unpredictable temporary names, never
// through a planted link), the check that a command's outputs name distinct files, and the text
// of bad input in messages.

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <drivenshape/error.h>
#include <drivenshape/frames.h>

#include "atomic_file.h"
#include "test_support.h"
#include "text.h"

namespace drivenshape {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

std::string readText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST(AtomicFile, TemporaryNamesAreUnpredictableAndCreatedExclusively) {
  TempDir dir;
  const std::string target = dir.file("out.exr");
  std::set<std::string> names;
  for (int i = 0; i < 50; ++i) {
    AtomicFile file(target);
    const std::string name = fs::path(file.tempPath()).filename().string();
    EXPECT_EQ(name.rfind(".out.exr.tmp-", 0), 0u) << name;
    EXPECT_EQ(name.size(), std::string(".out.exr.tmp-").size() + 16) << name;
    // Created by the constructor, as a regular file of its own (not through a link).
    EXPECT_TRUE(fs::is_regular_file(fs::symlink_status(file.tempPath()))) << name;
    names.insert(name);
  }
  EXPECT_EQ(names.size(), 50u) << "temporary names repeat";
  EXPECT_TRUE(fs::is_empty(dir.path())) << "abandoned temporary files are removed";
}

TEST(AtomicFile, ALinkAtTheTargetIsReplacedAndItsTargetKept) {
  TempDir dir;
  const std::string victim = dir.file("victim.txt");
  std::ofstream(victim) << "keep me";
  const std::string target = dir.file("out.json");
  fs::create_symlink(victim, target);
  writeFileAtomically(target, "new content");
  EXPECT_EQ(readText(victim), "keep me");
  EXPECT_TRUE(fs::is_regular_file(fs::symlink_status(target)));
  EXPECT_EQ(readText(target), "new content");

  AtomicFile file(dir.file("stream.bin"));
  file.stream() << "abcdef";
  file.stream().seekp(2);
  file.stream() << "XY";
  file.commit();
  EXPECT_EQ(readText(dir.file("stream.bin")), "abXYef");
}

/// The names in `folder`, sorted.
std::set<std::string> namesIn(const std::string& folder) {
  std::set<std::string> names;
  for (const auto& entry : fs::directory_iterator(folder)) {
    names.insert(entry.path().filename().string());
  }
  return names;
}

// A job template and its parameters file change together: both replaced, or neither.
TEST(AtomicFile, FilesWrittenTogetherChangeAsAPairOrNotAtAll) {
  TempDir dir;
  const std::string first = dir.file("job.params.json");
  const std::string second = dir.file("job.json");
  writeFilesTogether({{first, "old params"}, {second, "old job"}});
  const std::string victim = dir.file("victim.txt");
  std::ofstream(victim) << "keep me";
  fs::remove(second);
  fs::create_symlink(victim, second);
  writeFilesTogether({{first, "new params"}, {second, "new job"}});
  EXPECT_EQ(readText(first), "new params");
  EXPECT_EQ(readText(second), "new job");
  EXPECT_EQ(readText(victim), "keep me");
  EXPECT_EQ(namesIn(dir.path()),
            (std::set<std::string>{"job.json", "job.params.json", "victim.txt"}));  // no kept links

  // The second cannot be made (its folder is missing): the first stays as it was.
  testing::expectThrows(
      [&] {
        writeFilesTogether({{first, "newer params"}, {dir.file("none/job.json"), "x"}});
      },
      ErrorCode::kOutput, "none");
  EXPECT_EQ(readText(first), "new params");
  EXPECT_EQ(namesIn(dir.path()),
            (std::set<std::string>{"job.json", "job.params.json", "victim.txt"}));
}

TEST(AtomicFile, LongNamesGetShortTemporaryNamesAndTooLongOnesNameTheLimit) {
  TempDir dir;
  const std::string longest = dir.file(std::string(255, 'n'));
  writeFileAtomically(longest, "x");
  EXPECT_EQ(readText(longest), "x");
  std::string otherTemp;
  {
    AtomicFile file(dir.file(std::string(250, 'm')));
    const std::string temp = file.tempPath();
    EXPECT_LE(fs::path(temp).filename().string().size(), 255u);
    // A stale temporary file of the long name is found by its (shortened) prefix.
    std::ofstream(temp.substr(0, temp.size() - 16) + "0123456789abcdef") << "stale";
    // A long name that starts with the same 240 bytes has a prefix of its own (the hash of
    // the whole name): its writer's file is not the first name's.
    AtomicFile other(dir.file(std::string(240, 'm') + std::string(10, 'o')));
    otherTemp = other.tempPath();
    std::ofstream(otherTemp.substr(0, otherTemp.size() - 16) + "fedcba9876543210") << "other";
    EXPECT_NE(otherTemp.substr(0, otherTemp.size() - 16), temp.substr(0, temp.size() - 16));
  }
  EXPECT_EQ(removeStaleTempFiles({dir.file(std::string(250, 'm'))}), 1);
  EXPECT_TRUE(fs::exists(otherTemp.substr(0, otherTemp.size() - 16) + "fedcba9876543210"));
  testing::expectThrows([&] { AtomicFile file(dir.file(std::string(256, 'n'))); },
                        ErrorCode::kOutput, "255 bytes per name");
}

TEST(RequireRegularFile, FifosFoldersAndMissingFilesAreRefused) {
  TempDir dir;
  ASSERT_EQ(::mkfifo(dir.file("pipe").c_str(), 0600), 0);
  testing::expectThrows([&] { readWholeFile(dir.file("pipe"), "OBJ"); }, ErrorCode::kInput,
                        "is a FIFO");
  testing::expectThrows([&] { readWholeFile(dir.path(), "OBJ"); }, ErrorCode::kInput, "folder");
  testing::expectThrows([&] { readWholeFile(dir.file("none"), "OBJ"); }, ErrorCode::kInput,
                        "cannot read OBJ");
}

TEST(OutputFolders, MissingOnesAreNamedThenCreatedOnceAndAFileInTheWayIsRefused) {
  TempDir dir;
  const std::string output = dir.file("a/b/c/cloth.0001.exr");
  const std::vector<std::string> expected = {dir.file("a"), dir.file("a/b"), dir.file("a/b/c")};
  EXPECT_EQ(missingOutputFolders(output), expected);
  EXPECT_FALSE(fs::exists(dir.file("a"))) << "naming the missing folders creates nothing";
  fs::create_directories(dir.file("a"));
  EXPECT_EQ(createOutputFolders(output),
            std::vector<std::string>(expected.begin() + 1, expected.end()));
  EXPECT_TRUE(fs::is_directory(dir.file("a/b/c")));
  EXPECT_TRUE(createOutputFolders(output).empty()) << "folders that exist are not created again";
  EXPECT_TRUE(missingOutputFolders(output).empty());
  // A file where a folder should be: refused, naming it, before and when creating.
  std::ofstream(dir.file("file")) << "x";
  testing::expectThrows([&] { missingOutputFolders(dir.file("file/d/x.exr")); }, ErrorCode::kOutput,
                        "file/d");
  testing::expectThrows([&] { createOutputFolders(dir.file("file/d/x.exr")); }, ErrorCode::kOutput,
                        "file/d");
  testing::expectThrows([&] { createOutputFolders(dir.file("file/x.exr")); }, ErrorCode::kOutput,
                        "is not a folder");
  // Relative paths (the current folder is the nearest that exists).
  const fs::path previous = fs::current_path();
  fs::current_path(dir.path());
  EXPECT_EQ(createOutputFolders("rel/x.exr"), std::vector<std::string>{"rel"});
  fs::current_path(previous);
  EXPECT_TRUE(fs::is_directory(dir.file("rel")));
}

TEST(OutputFolders, TasksCreatingTheSameFoldersAtOnceAllSucceed) {
  TempDir dir;
  const std::string output = dir.file("shot/v001/cloth.0001.exr");
  std::vector<std::thread> tasks;
  std::vector<std::size_t> created(8, 0);
  for (std::size_t i = 0; i < created.size(); ++i) {
    tasks.emplace_back([&, i] { created[i] = createOutputFolders(output).size(); });
  }
  for (std::thread& task : tasks) {
    task.join();
  }
  std::size_t total = 0;
  for (std::size_t count : created) {
    total += count;
  }
  EXPECT_EQ(total, 2u) << "each folder is created by exactly one task";
  EXPECT_TRUE(fs::is_directory(dir.file("shot/v001")));
}

TEST(CheckDistinctPaths, OutputsNamingOneFileOrAnInputAreRefused) {
  TempDir dir;
  const std::vector<int> frames = {1, 2, 3};
  const std::string pattern = dir.file("a.####.exr");
  checkDistinctPaths({{"-o", pattern, true}, {"--report", dir.file("a.report.json"), false}},
                     frames, {{"--driver", dir.file("in.pc2"), false}});
  testing::expectThrows(
      [&] {
        checkDistinctPaths({{"-o", pattern, true}, {"--report", dir.file("a.0002.exr"), false}},
                           frames);
      },
      ErrorCode::kUsage, "-o '");
  // Another token of the same width, `..` and `.` name the same files.
  fs::create_directory(dir.file("sub"));
  testing::expectThrows(
      [&] {
        checkDistinctPaths(
            {{"-o", pattern, true}, {"--posmap-out", dir.file("sub/../a.%04d.exr"), true}}, frames);
      },
      ErrorCode::kUsage, "--posmap-out");
  testing::expectThrows(
      [&] {
        checkDistinctPaths({{"--json", dir.file("./a.0003.exr"), false}}, frames,
                           {{"--bake", pattern, true}});
      },
      ErrorCode::kUsage, "would overwrite the input --bake");
  // A link to the folder is the same folder.
  fs::create_directory_symlink(dir.path(), dir.file("link"));
  testing::expectThrows(
      [&] {
        checkDistinctPaths({{"--pc2", dir.file("x"), false}, {"--obj", dir.file("link/x"), false}},
                           {});
      },
      ErrorCode::kUsage, "--obj");
  // Frames outside the range do not collide.
  checkDistinctPaths({{"-o", pattern, true}, {"--report", dir.file("a.0009.exr"), false}}, frames);
}

TEST(PrintableText, EscapesBadBytesKeepsUtf8AndShortens) {
  EXPECT_EQ(printableText("last read: '\xf7'"), "last read: '\\xf7'");
  EXPECT_EQ(printableText("caf\xc3\xa9\n\t"), "caf\xc3\xa9\n\t");
  EXPECT_EQ(printableText(std::string("a\0b\x1b", 4)), "a\\x00b\\x1b");
  EXPECT_EQ(printableText("\xe2\x82"), "\\xe2\\x82");           // a cut sequence
  EXPECT_EQ(printableText("\xed\xa0\x80"), "\\xed\\xa0\\x80");  // a surrogate
  EXPECT_TRUE(isUtf8("caf\xc3\xa9 \xf0\x9f\x98\x80"));
  for (const char* bad :
       {"\xf7", "\xc0\xaf", "\xe0\x80\xaf", "\xed\xa0\x80", "\xf4\x90\x80\x80", "\xe2\x82"}) {
    EXPECT_FALSE(isUtf8(bad)) << printableText(bad);
  }
  const std::string shortened = printableText(std::string(5000, 'p'), 100);
  EXPECT_EQ(shortened, std::string(50, 'p') + "...(5000 bytes)..." + std::string(50, 'p'));
}

}  // namespace
}  // namespace drivenshape
