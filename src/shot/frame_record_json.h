// SPDX-License-Identifier: Apache-2.0
#pragma once

// One frame's record as JSON: the bake report's frames[] entry and the dsRecord attribute of
// every EXR a bake writes, so that a resume reports a kept frame exactly as the run that baked
// it did (the report is the shot's, whichever runs produced its frames).

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include <drivenshape/evaluator.h>

namespace drivenshape {

/// The EXR header attribute (string) holding the frame's record, frameRecordJson as one line.
inline constexpr const char* kAttrFrameRecord = "dsRecord";

/// What the frame's cloth is known by: its weights, residuals, audit counts, largest jump and
/// coverage. Neither the output path nor what one run did (kept, rebaked, work counters).
/// With regions (more weights than `shapeCount`) the weights are one list per region.
nlohmann::json frameRecordJson(const FrameRecord& record, int shapeCount);

/// The record frameRecordJson wrote, back (frameRecordJson of it gives the same JSON).
/// Error(kInput) naming `where` and the field for anything else.
FrameRecord frameRecordFromJson(const nlohmann::json& entry, const std::string& where);

/// The shot's coverage verdict from the records' error bounds (the report's `coverage`): the
/// fraction of frames the pose model covers, the frames to simulate and the runs a simulation
/// of them needs, counted from `shotStart` (else the first frame checked); null when no record
/// has a prediction.
nlohmann::json coverageJson(const std::vector<FrameRecord>& records, double tolerance, double level,
                            std::optional<int> shotStart);

}  // namespace drivenshape
