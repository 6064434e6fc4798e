// SPDX-License-Identifier: Apache-2.0
#pragma once

// A minimal parallel loop for independent items (frames, files): the host stages, the
// candidate search, EXR writing. Results never depend on the thread count, because each item
// writes only its own outputs.

#include <algorithm>
#include <atomic>
#include <exception>
#include <limits>
#include <mutex>
#include <thread>
#include <vector>

namespace drivenshape {

/// The machine's hardware threads (at least 1).
inline int hardwareThreads() {
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

/// `requested` threads (0 = one per hardware thread) within what the machine has: a request
/// above its hardware threads gets that many (more only slows the work down, and a large count
/// exhausts the threads a process may start, inside PoCL too).
inline int clampThreads(int requested) {
  return requested > 0 ? std::min(requested, hardwareThreads()) : requested;
}

/// Threads to use for `requested` (0 = one per hardware thread), never more than `work` nor
/// the machine's hardware threads.
inline int resolveThreads(int requested, int work) {
  const int threads = requested > 0 ? clampThreads(requested) : hardwareThreads();
  return std::max(1, std::min(threads, work));
}

/// Threads to use for `requested` (0 = one per hardware thread), at least 1.
inline int resolveThreads(int requested) {
  return resolveThreads(requested, std::numeric_limits<int>::max());
}

/// Calls body(i) for i in [0, count) on `threads` threads (0 = hardware). If bodies throw, the
/// exception of the smallest i is rethrown after all threads have stopped, so the error a user
/// sees does not depend on scheduling.
template <typename Body>
void parallelFor(int count, int threads, Body&& body) {
  const int workers = resolveThreads(threads, count);
  if (workers <= 1) {
    for (int i = 0; i < count; ++i) {
      body(i);
    }
    return;
  }
  std::atomic<int> next{0};
  std::mutex mutex;
  int failedIndex = count;
  std::exception_ptr failure;
  auto work = [&]() {
    for (int i = next++; i < count; i = next++) {
      try {
        body(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        if (i < failedIndex) {
          failedIndex = i;
          failure = std::current_exception();
        }
      }
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(static_cast<std::size_t>(workers - 1));
  for (int w = 1; w < workers; ++w) {
    pool.emplace_back(work);
  }
  work();
  for (std::thread& thread : pool) {
    thread.join();
  }
  if (failure) {
    std::rethrow_exception(failure);
  }
}

}  // namespace drivenshape
