// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <iosfwd>
#include <memory>
#include <string>

#include <drivenshape/device.h>

namespace drivenshape::cli {

/// The device for --device SPEC (see drivenshape::openDevice). `log` gets a warning when
/// `auto` finds no OpenCL device and falls back to the host path.
std::unique_ptr<Device> openCliDevice(const std::string& spec, std::ostream& log);

}  // namespace drivenshape::cli
