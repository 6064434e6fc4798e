// SPDX-License-Identifier: Apache-2.0
#include "device_choice.h"

#include <ostream>

namespace drivenshape::cli {

std::unique_ptr<Device> openCliDevice(const std::string& spec, std::ostream& log) {
  std::string note;
  std::unique_ptr<Device> device = openDevice(spec, &note);
  if (!note.empty()) {
    log << "warning: " << note << "\n";
  }
  return device;
}

}  // namespace drivenshape::cli
