# SPDX-License-Identifier: MIT
# One place for language standard, warnings, include root and sanitizers.
set(CMAKE_CXX_STANDARD 20)
set(CMAKE_CXX_STANDARD_REQUIRED ON)
set(CMAKE_CXX_EXTENSIONS OFF)
set(CMAKE_POSITION_INDEPENDENT_CODE ON)

if(PITMAP_SANITIZE)
  string(REPLACE "," ";" _pitmap_san_list "${PITMAP_SANITIZE}")
  add_compile_options(-fsanitize=${PITMAP_SANITIZE} -fno-omit-frame-pointer -fno-sanitize-recover=all)
  # After -fsanitize=, so that it wins (clang and GCC read these flags left to right).
  if(PITMAP_SANITIZE_EXCLUDE)
    add_compile_options(-fno-sanitize=${PITMAP_SANITIZE_EXCLUDE})
  endif()
  # GCC's sanitizer instrumentation makes -Wmaybe-uninitialized report false positives inside
  # libstdc++ (std::regex, std::function in GCC 12); the Release build keeps the warning.
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    add_compile_options(-Wno-maybe-uninitialized)
  endif()
  add_link_options(-fsanitize=${PITMAP_SANITIZE})
endif()

# pitmap_target_defaults(<target>): standard warnings and the repository root as include root.
function(pitmap_target_defaults target)
  target_compile_features(${target} PUBLIC cxx_std_20)
  get_target_property(_type ${target} TYPE)
  if(_type STREQUAL "INTERFACE_LIBRARY")
    target_include_directories(${target} INTERFACE ${PROJECT_SOURCE_DIR})
    return()
  endif()
  target_include_directories(${target} PUBLIC ${PROJECT_SOURCE_DIR})
  target_compile_options(${target} PRIVATE
    -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wcast-align
    -Woverloaded-virtual -Wimplicit-fallthrough
    # GCC 12 reports false -Wrestrict positives inside std::string operator+ at -O2/-O3
    # (GCC bug 105329); the warning is sound on clang and later GCCs.
    $<$<CXX_COMPILER_ID:GNU>:-Wno-restrict>
    $<$<BOOL:${PITMAP_WARNINGS_AS_ERRORS}>:-Werror>)
endfunction()

# pitmap_add_library(<name> <alias> SOURCES... ) : one static library per folder.
function(pitmap_add_library name alias)
  add_library(${name} STATIC ${ARGN})
  add_library(${alias} ALIAS ${name})
  pitmap_target_defaults(${name})
endfunction()

# pitmap_add_executable(<name> SOURCES...): a thin executable, output in build/bin.
function(pitmap_add_executable name)
  add_executable(${name} ${ARGN})
  pitmap_target_defaults(${name})
endfunction()
