# SPDX-License-Identifier: Apache-2.0
# `cmake --install build --prefix PREFIX` puts the library (static archives), the public headers,
# the command line and a package configuration in PREFIX, so that a studio's project can
# find_package(drivenshape) and link drivenshape::drivenshape (tests/package checks this from a
# consumer project outside the tree).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(DS_INSTALL_CMAKEDIR "${CMAKE_INSTALL_LIBDIR}/cmake/drivenshape")

install(TARGETS drivenshape
        EXPORT drivenshapeTargets
        ARCHIVE DESTINATION "${CMAKE_INSTALL_LIBDIR}"
        INCLUDES DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}")
if(TARGET drivenshape_cli)
  install(TARGETS drivenshape_cli EXPORT drivenshapeTargets
          RUNTIME DESTINATION "${CMAKE_INSTALL_BINDIR}")
  # The add-on's module: `drivenshape simulate` runs its simulate_window.py in Blender.
  install(DIRECTORY "${PROJECT_SOURCE_DIR}/apps/blender/drivenshape_blender"
          DESTINATION "${CMAKE_INSTALL_DATADIR}/drivenshape/blender"
          PATTERN "__pycache__" EXCLUDE)
endif()
install(DIRECTORY "${PROJECT_SOURCE_DIR}/src/include/drivenshape"
        DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}" FILES_MATCHING PATTERN "*.h")
install(FILES "${PROJECT_BINARY_DIR}/include/drivenshape/version.h"
        DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}/drivenshape")
install(EXPORT drivenshapeTargets NAMESPACE drivenshape:: DESTINATION "${DS_INSTALL_CMAKEDIR}")

configure_package_config_file("${PROJECT_SOURCE_DIR}/cmake/drivenshapeConfig.cmake.in"
                              "${PROJECT_BINARY_DIR}/drivenshapeConfig.cmake"
                              INSTALL_DESTINATION "${DS_INSTALL_CMAKEDIR}")
write_basic_package_version_file("${PROJECT_BINARY_DIR}/drivenshapeConfigVersion.cmake"
                                 VERSION "${PROJECT_VERSION}" COMPATIBILITY SameMinorVersion)
install(FILES "${PROJECT_BINARY_DIR}/drivenshapeConfig.cmake"
              "${PROJECT_BINARY_DIR}/drivenshapeConfigVersion.cmake"
        DESTINATION "${DS_INSTALL_CMAKEDIR}")
