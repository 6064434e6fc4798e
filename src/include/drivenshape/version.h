// SPDX-License-Identifier: Apache-2.0
#pragma once

namespace drivenshape {

/// The library version, "MAJOR.MINOR.PATCH"; written into every output file.
inline constexpr const char* kVersion = DRIVENSHAPE_VERSION_STRING;

}  // namespace drivenshape
