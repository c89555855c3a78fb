# SPDX-License-Identifier: MIT
# Every dependency comes from Debian 12 packages; tools/install-deps.sh installs them.
# Where a package ships no CMake config, a small find module in cmake/ fills in.
find_package(Threads REQUIRED)
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(ZLIB REQUIRED)
find_package(yaml-cpp REQUIRED)
find_package(CLI11 REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
find_package(LCM REQUIRED)           # cmake/FindLCM.cmake -> lcm::lcm, LCM_GEN_EXECUTABLE
find_package(GeographicLib REQUIRED) # cmake/FindGeographicLib.cmake -> GeographicLib::GeographicLib
find_package(PCAP REQUIRED)          # cmake/FindPCAP.cmake -> PCAP::PCAP

if(PITMAP_BUILD_PROCESSOR)
  find_package(CHOLMOD REQUIRED)     # cmake/FindCHOLMOD.cmake -> SuiteSparse::CHOLMOD
  find_package(TBB REQUIRED CONFIG)
  find_package(nanoflann REQUIRED)
  list(APPEND CMAKE_MODULE_PATH /usr/lib/${CMAKE_LIBRARY_ARCHITECTURE}/cmake/OpenVDB)
  find_package(OpenVDB REQUIRED)
  find_package(GDAL CONFIG REQUIRED)  # GeoTIFF (COG) and BAG grids -> GDAL::GDAL
  find_package(PROJ CONFIG REQUIRED)  # geoid grids (proj-data's egm96_15.gtx) -> PROJ::proj
  # Clang's UBSan reports a downcast of oneTBB's sentinel pointer inside every OpenVDB tree
  # merge (third-party, harmless; cmake/ubsan-ignorelist.txt says what and where): whatever
  # compiles OpenVDB headers leaves that one check of that one TBB header out.
  if(PITMAP_SANITIZE MATCHES "undefined" AND CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    target_compile_options(OpenVDB::openvdb INTERFACE
      -fsanitize-ignorelist=${PROJECT_SOURCE_DIR}/cmake/ubsan-ignorelist.txt)
  endif()
endif()

if(PITMAP_BUILD_TESTS)
  find_package(GTest REQUIRED)
  if(PITMAP_BUILD_PROCESSOR)
    find_package(assimp CONFIG REQUIRED)  # reads the exported meshes back in tests
  endif()
endif()
if(PITMAP_BUILD_BENCHMARKS)
  find_package(benchmark REQUIRED)
endif()
