#pragma once

#include <algorithm>
#include <exception>
#include <thread>
#include <vector>

namespace drivenshape {

/// Runs body(i) for i in [0, count) on up to `threads` threads (items are independent and
/// each writes only its own outputs, so the result does not depend on the thread count).
/// The first exception by item index is rethrown after all threads finish.
template <typename Body>
void parallelFor(int count, int threads, Body&& body) {
  threads = std::max(1, std::min(threads, count));
  std::vector<std::exception_ptr> errors(static_cast<std::size_t>(std::max(count, 0)));
  auto run = [&](int first) {
    for (int i = first; i < count; i += threads) {
      try {
        body(i);
      } catch (...) {
        errors[static_cast<std::size_t>(i)] = std::current_exception();
      }
    }
  };
  if (threads == 1) {
    run(0);
  } else {
    std::vector<std::thread> pool;
    pool.reserve(static_cast<std::size_t>(threads));
    for (int t = 0; t < threads; ++t) {
      pool.emplace_back(run, t);
    }
    for (auto& thread : pool) {
      thread.join();
    }
  }
  for (auto& error : errors) {
    if (error) {
      std::rethrow_exception(error);
    }
  }
}

}  // namespace drivenshape
