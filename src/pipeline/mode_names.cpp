// SPDX-License-Identifier: Apache-2.0
// The names of the evaluator's modes (drivenshape/evaluator.h), apart from the evaluator so that
// the settings table and what reads it (the fuzz targets' readers) need nothing of the
// pipeline.

#include <drivenshape/evaluator.h>

namespace drivenshape {

const char* alignModeName(AlignMode mode) {
  switch (mode) {
    case AlignMode::kNone:
      return "none";
    case AlignMode::kRigid:
      return "rigid";
    case AlignMode::kRigidAll:
      return "rigid-all";
  }
  return "?";
}

const char* weightModeName(WeightMode mode) {
  switch (mode) {
    case WeightMode::kQp:
      return "qp";
    case WeightMode::kNearest:
      return "nearest";
    case WeightMode::kBind:
      return "bind";
    case WeightMode::kModel:
      return "model";
    case WeightMode::kAuto:
      return "auto";
  }
  return "?";
}

const char* blendModeName(BlendMode mode) {
  return mode == BlendMode::kLocal ? "local" : "world";
}

const char* resolveDirectionName(ResolveDirection direction) {
  return direction == ResolveDirection::kNearest ? "nearest" : "normal";
}

}  // namespace drivenshape
