// SPDX-License-Identifier: Apache-2.0
// qp_solve_tool: solves blend-weight problems from a file with SimplexLeastSquares, for tests
// that compare it with other solvers (tests/database/test_qp_quadprog.py). Built only for tests.
//
//   qp_solve_tool INPUT OUTPUT
//
// All numbers little-endian; int32 and float64, packed without padding.
//
//   INPUT   "DSQPIN01"  int32 databases
//           per database:  int32 n, int32 k, int32 frames,
//                          float64 A[n * k]        column-major: shape j is A[j*n .. j*n+n-1]
//                          float64 b[frames * n]   frame-major
//
//   OUTPUT  "DSQPOUT1"  int32 problems              (the sum of frames over the databases)
//           per problem:   int32 k, int32 status (0, or the drivenshape ErrorCode that the
//                          solve threw; its message goes to stderr), int32 iterations,
//                          float64 objective, relativeResidual, kktResidual, sumError,
//                          boundViolation, float64 weights[k]
//
// A failed problem is reported and the others are still solved. Exit codes: 0 done (whatever
// the statuses), 2 usage, 3 unreadable or malformed input, 4 output not written.

#include <drivenshape/error.h>

#include "qp.h"

#include <Eigen/Core>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace {

using drivenshape::Error;
using drivenshape::ErrorCode;

struct Database {
  Eigen::MatrixXd shapes;  // n by k
  Eigen::MatrixXd frames;  // n by frames
};

class Reader {
 public:
  explicit Reader(const std::string& path) : mPath(path), mStream(path, std::ios::binary) {
    if (!mStream) {
      DS_THROW(kInput, path, ": cannot open for reading");
    }
  }
  void bytes(void* data, std::size_t size) {
    if (!mStream.read(static_cast<char*>(data), static_cast<std::streamsize>(size))) {
      DS_THROW(kInput, mPath, ": truncated (", size, " more bytes expected)");
    }
  }
  std::int32_t int32() {
    std::int32_t value = 0;
    bytes(&value, sizeof value);
    return value;
  }
  void doubles(double* data, Eigen::Index count) {
    bytes(data, static_cast<std::size_t>(count) * sizeof(double));
  }

 private:
  std::string mPath;
  std::ifstream mStream;
};

std::vector<Database> readDatabases(const std::string& path) {
  Reader reader(path);
  char magic[8];
  reader.bytes(magic, sizeof magic);
  if (std::memcmp(magic, "DSQPIN01", 8) != 0) {
    DS_THROW(kInput, path, ": not a qp_solve_tool input (magic DSQPIN01 expected)");
  }
  const std::int32_t count = reader.int32();
  if (count < 0) {
    DS_THROW(kInput, path, ": negative database count ", count);
  }
  std::vector<Database> databases(static_cast<std::size_t>(count));
  for (std::int32_t d = 0; d < count; ++d) {
    const std::int32_t n = reader.int32();
    const std::int32_t k = reader.int32();
    const std::int32_t frames = reader.int32();
    if (n < 0 || k < 1 || frames < 0) {
      DS_THROW(kInput, path, ": database ", d, " has n = ", n, ", k = ", k, ", frames = ", frames);
    }
    Database& db = databases[static_cast<std::size_t>(d)];
    db.shapes.resize(n, k);
    reader.doubles(db.shapes.data(), db.shapes.size());
    db.frames.resize(n, frames);
    reader.doubles(db.frames.data(), db.frames.size());
  }
  return databases;
}

class Writer {
 public:
  explicit Writer(const std::string& path) : mPath(path), mStream(path, std::ios::binary) {
    if (!mStream) {
      DS_THROW(kOutput, path, ": cannot open for writing");
    }
  }
  void bytes(const void* data, std::size_t size) {
    if (!mStream.write(static_cast<const char*>(data), static_cast<std::streamsize>(size))) {
      DS_THROW(kOutput, mPath, ": write failed");
    }
  }
  void int32(std::int32_t value) { bytes(&value, sizeof value); }
  void float64(double value) { bytes(&value, sizeof value); }
  void close() {
    mStream.close();
    if (!mStream) {
      DS_THROW(kOutput, mPath, ": write failed");
    }
  }

 private:
  std::string mPath;
  std::ofstream mStream;
};

void solveAll(const std::string& inputPath, const std::string& outputPath) {
  const std::vector<Database> databases = readDatabases(inputPath);
  std::int32_t problems = 0;
  for (const Database& db : databases) {
    problems += static_cast<std::int32_t>(db.frames.cols());
  }
  Writer writer(outputPath);
  writer.bytes("DSQPOUT1", 8);
  writer.int32(problems);
  for (std::size_t d = 0; d < databases.size(); ++d) {
    const Database& db = databases[d];
    const auto k = static_cast<std::int32_t>(db.shapes.cols());
    std::string setupFailure;
    ErrorCode setupCode = ErrorCode::kInternal;
    std::optional<drivenshape::SimplexLeastSquares> solver;
    try {
      solver.emplace(db.shapes);
    } catch (const Error& error) {
      setupCode = error.code();
      setupFailure = error.what();
    }
    for (Eigen::Index f = 0; f < db.frames.cols(); ++f) {
      drivenshape::SimplexSolution solution;
      int status = 0;
      if (!solver) {
        status = static_cast<int>(setupCode);
        std::fprintf(stderr, "database %zu: %s\n", d, setupFailure.c_str());
      } else {
        try {
          solution = solver->solve(db.frames.col(f));
        } catch (const Error& error) {
          status = static_cast<int>(error.code());
          std::fprintf(stderr, "database %zu, frame %ld: %s\n", d, static_cast<long>(f),
                       error.what());
        }
      }
      if (solution.weights.size() != k) {
        solution.weights = Eigen::VectorXd::Constant(k, std::numeric_limits<double>::quiet_NaN());
      }
      writer.int32(k);
      writer.int32(status);
      writer.int32(solution.iterations);
      writer.float64(solution.objective);
      writer.float64(solution.relativeResidual);
      writer.float64(solution.kktResidual);
      writer.float64(solution.sumError);
      writer.float64(solution.boundViolation);
      writer.bytes(solution.weights.data(), static_cast<std::size_t>(k) * sizeof(double));
    }
  }
  writer.close();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: qp_solve_tool INPUT OUTPUT\n");
    return static_cast<int>(ErrorCode::kUsage);
  }
  try {
    solveAll(argv[1], argv[2]);
  } catch (const Error& error) {
    std::fprintf(stderr, "qp_solve_tool: %s: %s\n", drivenshape::errorCodeName(error.code()),
                 error.what());
    return static_cast<int>(error.code());
  } catch (const std::exception& error) {
    std::fprintf(stderr, "qp_solve_tool: internal error: %s\n", error.what());
    return static_cast<int>(ErrorCode::kInternal);
  }
  return 0;
}
