# SPDX-License-Identifier: MIT
# Debian's LCM 1.3.1 ships no CMake config, and its lcm.pc needs glib-dev; find it directly.
find_path(LCM_INCLUDE_DIR lcm/lcm-cpp.hpp)
find_library(LCM_LIBRARY lcm)
find_program(LCM_GEN_EXECUTABLE lcm-gen)
find_program(LCM_LOGPLAYER_EXECUTABLE lcm-logplayer)
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(LCM REQUIRED_VARS LCM_LIBRARY LCM_INCLUDE_DIR LCM_GEN_EXECUTABLE)
if(LCM_FOUND AND NOT TARGET lcm::lcm)
  add_library(lcm::lcm UNKNOWN IMPORTED)
  set_target_properties(lcm::lcm PROPERTIES
    IMPORTED_LOCATION "${LCM_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${LCM_INCLUDE_DIR}")
endif()
mark_as_advanced(LCM_INCLUDE_DIR LCM_LIBRARY LCM_GEN_EXECUTABLE LCM_LOGPLAYER_EXECUTABLE)
