// SPDX-License-Identifier: Apache-2.0
// Machine ceilings for the roofline note in docs/performance.md (issue 5): the measured peak of a
// dense float GEMM (compute roof) and of streaming copy and triad loops (memory roof), on one
// thread and on every thread at once. Not a test: run it by hand.
//
//   bench_roofline [--threads N] [--repeat 5] [--gemm 768] [--stream-mib 256]
//
// The GEMM is Eigen's (single-threaded per thread, compiled for the host CPU), the streaming
// loops plain C++ the compiler vectorises; each thread works on its own arrays, so the
// all-thread figures are what the cores reach together. Reports the best of --repeat passes.

#include <Eigen/Core>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

struct Options {
  int threads = 0;
  int repeat = 5;
  int gemm = 768;
  int streamMiB = 256;
};

Options parse(int argc, char** argv) {
  Options options;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--help" || flag == "-h") {
      std::puts("bench_roofline [--threads N] [--repeat 5] [--gemm 768] [--stream-mib 256]");
      std::exit(0);
    }
    if (i + 1 >= argc) {
      std::fprintf(stderr, "bench_roofline: %s needs a value\n", flag.c_str());
      std::exit(2);
    }
    const int value = std::atoi(argv[++i]);
    if (value < 0 || (value == 0 && flag != "--threads")) {
      std::fprintf(stderr, "bench_roofline: %s needs a positive number\n", flag.c_str());
      std::exit(2);
    }
    if (flag == "--threads") {
      options.threads = value;
    } else if (flag == "--repeat") {
      options.repeat = value;
    } else if (flag == "--gemm") {
      options.gemm = value;
    } else if (flag == "--stream-mib") {
      options.streamMiB = value;
    } else {
      std::fprintf(stderr, "bench_roofline: unknown flag %s\n", flag.c_str());
      std::exit(2);
    }
  }
  if (options.threads == 0) {
    options.threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  }
  return options;
}

/// Runs `work(thread)` on `threads` threads at once and returns the best wall time of `repeat`
/// passes (after one warm-up pass).
template <typename Work>
double bestSeconds(int threads, int repeat, Work work) {
  double best = 1e300;
  for (int pass = 0; pass <= repeat; ++pass) {
    const auto start = Clock::now();
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) {
      pool.emplace_back([&work, t] { work(t); });
    }
    for (std::thread& thread : pool) {
      thread.join();
    }
    const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
    if (pass > 0) {
      best = std::min(best, seconds);
    }
  }
  return best;
}

/// GFLOP/s of n x n float GEMMs, one per thread.
double gemmGflops(int threads, int repeat, int n) {
  std::vector<Eigen::MatrixXf> a(threads), b(threads), c(threads);
  for (int t = 0; t < threads; ++t) {
    a[t] = Eigen::MatrixXf::Random(n, n);
    b[t] = Eigen::MatrixXf::Random(n, n);
    c[t] = Eigen::MatrixXf::Zero(n, n);
  }
  const double seconds = bestSeconds(threads, repeat, [&](int t) { c[t].noalias() = a[t] * b[t]; });
  return 2.0 * n * double(n) * n * threads / seconds * 1e-9;
}

struct StreamRates {
  double copy = 0;   ///< GB/s, bytes read + written
  double triad = 0;  ///< GB/s, bytes read + written
};

StreamRates streamRates(int threads, int repeat, int mib) {
  const std::size_t count = std::size_t(mib) * 1024 * 1024 / sizeof(float) / 3 / threads;
  std::vector<std::vector<float>> x(threads), y(threads), z(threads);
  for (int t = 0; t < threads; ++t) {
    x[t].assign(count, 1.0f);
    y[t].assign(count, 2.0f);
    z[t].assign(count, 0.0f);
  }
  StreamRates rates;
  const double bytes = double(count) * sizeof(float) * threads;
  double seconds = bestSeconds(threads, repeat, [&](int t) {
    const float* in = x[t].data();
    float* out = z[t].data();
    for (std::size_t i = 0; i < count; ++i) {
      out[i] = in[i];
    }
  });
  rates.copy = 2.0 * bytes / seconds * 1e-9;
  seconds = bestSeconds(threads, repeat, [&](int t) {
    const float* in0 = x[t].data();
    const float* in1 = y[t].data();
    float* out = z[t].data();
    for (std::size_t i = 0; i < count; ++i) {
      out[i] = in0[i] + 0.5f * in1[i];
    }
  });
  rates.triad = 3.0 * bytes / seconds * 1e-9;
  return rates;
}

}  // namespace

int main(int argc, char** argv) {
  const Options options = parse(argc, argv);
  std::printf("%-10s %8s %14s %12s %12s\n", "threads", "", "GEMM GFLOP/s", "copy GB/s",
              "triad GB/s");
  for (int threads : {1, options.threads}) {
    const double gflops = gemmGflops(threads, options.repeat, options.gemm);
    const StreamRates rates = streamRates(threads, options.repeat, options.streamMiB);
    std::printf("%-10d %8s %14.1f %12.1f %12.1f\n", threads, "", gflops, rates.copy, rates.triad);
    if (options.threads == 1) {
      break;
    }
  }
  return 0;
}
