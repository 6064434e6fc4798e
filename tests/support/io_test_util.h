// SPDX-License-Identifier: Apache-2.0
#pragma once
// Small helpers shared by the tests of src/io, the layers and the commands: catching a
// drivenshape::Error, raw file access.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <drivenshape/error.h>

namespace drivenshape::testing {

/// Runs `body` and returns the drivenshape::Error it throws; a test failure if none is thrown.
template <typename Body>
Error catchError(Body&& body) {
  try {
    body();
  } catch (const Error& error) {
    return error;
  }
  ADD_FAILURE() << "expected a drivenshape::Error, none was thrown";
  return Error(ErrorCode::kInternal, "<no error thrown>");
}

/// gtest matcher-free substring check with the whole message in the failure output.
inline ::testing::AssertionResult contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) {
    return ::testing::AssertionSuccess();
  }
  return ::testing::AssertionFailure() << "'" << part << "' not found in: " << text;
}

inline void writeTextFile(const std::string& path, const std::string& text) {
  std::ofstream stream(path, std::ios::binary);
  stream << text;
  ASSERT_TRUE(stream.good()) << path;
}

inline std::vector<unsigned char> readBytes(const std::string& path) {
  std::ifstream stream(path, std::ios::binary);
  return std::vector<unsigned char>(std::istreambuf_iterator<char>(stream), {});
}

inline void writeBytes(const std::string& path, const std::vector<unsigned char>& bytes) {
  std::ofstream stream(path, std::ios::binary);
  stream.write(reinterpret_cast<const char*>(bytes.data()),
               static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(stream.good()) << path;
}

/// Names of everything in `folder` (temporary files included), sorted.
inline std::vector<std::string> listFolder(const std::string& folder) {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

}  // namespace drivenshape::testing
