// SPDX-License-Identifier: Apache-2.0
#include "progress.h"

#include <unistd.h>

#include <algorithm>

namespace drivenshape {

Progress::Progress(std::string label, long total, std::FILE* stream)
    : mLabel(std::move(label)),
      mTotal(std::max(total, 1L)),
      mTerminal(::isatty(::fileno(stream)) != 0),
      mStream(stream),
      mStart(std::chrono::steady_clock::now()),
      mLastDraw(mStart) {}

Progress::~Progress() {
  finish();
}

void Progress::advance(long count) {
  mDone = std::min(mTotal, mDone + count);
  draw();
}

void Progress::draw() {
  const int percent = static_cast<int>(100 * mDone / mTotal);
  const auto now = std::chrono::steady_clock::now();
  if (!mTerminal) {
    if (percent != mLastPercent) {
      std::fprintf(mStream, "ALF_PROGRESS %d%%\n", percent);
      std::fflush(mStream);
      mLastPercent = percent;
    }
    return;
  }
  // Redraw at most 10 times a second, and always at the end.
  if (mDone < mTotal && now - mLastDraw < std::chrono::milliseconds(100) && mLastPercent >= 0) {
    return;
  }
  mLastDraw = now;
  mLastPercent = percent;
  const double elapsed = std::chrono::duration<double>(now - mStart).count();
  const double eta = mDone > 0 ? elapsed * static_cast<double>(mTotal - mDone) / mDone : 0.0;
  constexpr int kWidth = 30;
  const int filled = static_cast<int>(kWidth * mDone / mTotal);
  std::string bar(static_cast<std::size_t>(filled), '#');
  bar.resize(kWidth, '.');
  std::fprintf(mStream, "\r%s [%s] %ld/%ld %3d%% ETA %.1fs ", mLabel.c_str(), bar.c_str(), mDone,
               mTotal, percent, eta);
  std::fflush(mStream);
}

void Progress::finish() {
  if (mFinished) {
    return;
  }
  mFinished = true;
  if (mTerminal && mLastPercent >= 0) {
    std::fprintf(mStream, "\n");
    std::fflush(mStream);
  }
}

}  // namespace drivenshape
