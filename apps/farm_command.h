// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <string>
#include <vector>

namespace drivenshape::cli {

/// `drivenshape farm slurm|openjd`: writes a scheduler job for a shot bake, one task per frame
/// chunk (`bake --chunk-size N --chunk-index I --skip-existing`), so that a killed or retried
/// task resumes where it stopped. `slurm` writes an sbatch array script (and submits it with
/// --submit); `openjd` writes an Open Job Description 2023-09 job template (JSON or YAML).
/// The job, its script and its template are the library's (src/shot/farm_job.h); this parses
/// the options into a FarmJob, calls it and writes the files.
/// Returns the exit code; errors propagate as drivenshape::Error to main's single catch.
int runFarm(const std::vector<std::string>& args);

}  // namespace drivenshape::cli
