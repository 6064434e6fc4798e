// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <chrono>
#include <cstdio>
#include <string>

namespace drivenshape {

/// Progress on stderr for long work. On a terminal: a bar with a count and ETA redrawn in
/// place. Otherwise (farm logs): a plain `ALF_PROGRESS n%` line each time the percentage
/// changes. Thread-compatible, not thread-safe: report from one thread.
class Progress {
 public:
  Progress(std::string label, long total, std::FILE* stream = stderr);
  ~Progress();
  void advance(long count = 1);
  /// Ends the bar (newline on a terminal). Called by the destructor if not called.
  void finish();
  bool isTerminal() const { return mTerminal; }

 private:
  void draw();
  std::string mLabel;
  long mTotal;
  long mDone = 0;
  int mLastPercent = -1;
  bool mTerminal;
  bool mFinished = false;
  std::FILE* mStream;
  std::chrono::steady_clock::time_point mStart;
  std::chrono::steady_clock::time_point mLastDraw;
};

}  // namespace drivenshape
