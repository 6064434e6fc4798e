// SPDX-License-Identifier: Apache-2.0
#include <drivenshape/error.h>

namespace drivenshape {

const char* errorCodeName(ErrorCode code) {
  switch (code) {
    case ErrorCode::kInternal:
      return "internal error";
    case ErrorCode::kUsage:
      return "usage error";
    case ErrorCode::kInput:
      return "input error";
    case ErrorCode::kOutput:
      return "output error";
    case ErrorCode::kDevice:
      return "device error";
    case ErrorCode::kNumerical:
      return "numerical error";
    case ErrorCode::kInterrupted:
      return "interrupted";
  }
  return "error";
}

}  // namespace drivenshape
