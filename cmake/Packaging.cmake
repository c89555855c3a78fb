# SPDX-License-Identifier: MIT
# Debian packages with CPack (docs/packages.md; tools/build-packages.sh builds both):
#   pitmap-acqd  the vehicle: the daemon, its unit, sysusers/tmpfiles/sysctl snippets, an
#                example config; from the daemon-only build (PITMAP_BUILD_PROCESSOR=OFF).
#   pitmap       the shore: pitmap, pitmap-live, pitmap-report with its viewer scripts,
#                pitmap-sim, pitmap-eval, pitmap-inspect; from the full build.
# One install component per package (cmake/InstallDirs.cmake). A build folder packages the
# component its configuration is for: the daemon-only build `acqd`, the full build `shore`
# (PITMAP_PACKAGES overrides, e.g. "acqd;shore"). The package's prefix is the build's
# CMAKE_INSTALL_PREFIX (/usr for Debian packages: the scripts pass it), so the unit's
# ExecStart and the maintainer scripts name the paths the package really installs.
if(PITMAP_BUILD_PROCESSOR)
  set(_default_packages shore)
else()
  set(_default_packages acqd)
endif()
set(PITMAP_PACKAGES "${_default_packages}" CACHE STRING
    "install components `cpack` packages: acqd (pitmap-acqd), shore (pitmap)")
set(PITMAP_PACKAGE_VERSION "${PROJECT_VERSION}" CACHE STRING
    "Debian version of the packages (upstream version, optionally -revision)")

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME pitmap)
set(CPACK_PACKAGE_VENDOR "pitmap")
set(CPACK_PACKAGE_VERSION "${PITMAP_PACKAGE_VERSION}")
set(CPACK_PACKAGE_CONTACT "pitmap maintainers <maintainers@users.noreply.example>")
set(CPACK_PACKAGING_INSTALL_PREFIX "${CMAKE_INSTALL_PREFIX}")
set(CPACK_PACKAGE_DIRECTORY "${CMAKE_BINARY_DIR}/packages")
set(CPACK_STRIP_FILES ON)
set(CPACK_COMPONENTS_ALL ${PITMAP_PACKAGES})
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # <name>_<version>_<arch>.deb
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
# Shared-library dependencies computed by dpkg-shlibdeps (dpkg-dev), appended to the ones below.
# A cross build computes them itself against its sysroot (dpkg-shlibdeps reads the installed
# packages' symbols files, which a sysroot is not: tools/build-arm64.sh) and gives them here.
set(PITMAP_PACKAGE_SHLIBS_DEPENDS "" CACHE STRING
    "shared-library Depends computed outside CPack (cross builds); empty = dpkg-shlibdeps")
if(PITMAP_PACKAGE_SHLIBS_DEPENDS)
  set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS OFF)
  set(_shlibs_depends ", ${PITMAP_PACKAGE_SHLIBS_DEPENDS}")
else()
  set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
  set(_shlibs_depends "")
endif()
# A cross build (cmake/toolchain-aarch64-linux-gnu.cmake) says which architecture it builds for;
# otherwise CPack asks dpkg (the build machine's).
if(PITMAP_DEBIAN_ARCHITECTURE)
  set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${PITMAP_DEBIAN_ARCHITECTURE})
endif()

# Maintainer scripts: cmake/debian/<package>/, the paths of this prefix filled in.
set(PITMAP_FULL_SYSTEMDDIR "${CMAKE_INSTALL_PREFIX}/${PITMAP_INSTALL_SYSTEMDDIR}")
set(PITMAP_FULL_PROGRAMDIR "${CMAKE_INSTALL_PREFIX}/${PITMAP_INSTALL_PROGRAMDIR}")
function(_pitmap_control_files package out_var)
  set(_files)
  file(GLOB _in ${CMAKE_CURRENT_LIST_DIR}/debian/${package}/*.in)
  foreach(f ${_in})
    get_filename_component(_name ${f} NAME_WLE)
    # Scripts 0755, the conffiles list 0644.
    set(_mode OWNER_READ OWNER_WRITE GROUP_READ WORLD_READ)
    if(NOT _name STREQUAL "conffiles")
      list(APPEND _mode OWNER_EXECUTE GROUP_EXECUTE WORLD_EXECUTE)
    endif()
    configure_file(${f} ${CMAKE_BINARY_DIR}/debian/${package}/${_name} @ONLY
                   FILE_PERMISSIONS ${_mode})
    list(APPEND _files ${CMAKE_BINARY_DIR}/debian/${package}/${_name})
  endforeach()
  set(${out_var} ${_files} PARENT_SCOPE)
endfunction()

# Each package's /usr/share/doc/<package>/: the copyright (MIT) and a changelog naming the
# version and the commit it was built from (Debian policy 12.5 and 12.7).
find_package(Git QUIET)
set(_commit "unknown commit")
if(GIT_FOUND)
  execute_process(COMMAND ${GIT_EXECUTABLE} -C ${PROJECT_SOURCE_DIR} rev-parse --short=12 HEAD
                  OUTPUT_VARIABLE _git_head OUTPUT_STRIP_TRAILING_WHITESPACE
                  RESULT_VARIABLE _git_rc ERROR_QUIET)
  if(_git_rc EQUAL 0)
    set(_commit "commit ${_git_head}")
  endif()
endif()
string(TIMESTAMP _changelog_date "%a, %d %b %Y %H:%M:%S +0000" UTC)  # honours SOURCE_DATE_EPOCH
foreach(_pkg_comp pitmap-acqd:acqd pitmap:shore)
  string(REPLACE ":" ";" _pc ${_pkg_comp})
  list(GET _pc 0 _pkg)
  list(GET _pc 1 _comp)
  set(_doc ${CMAKE_BINARY_DIR}/debian/${_pkg}/doc)
  file(MAKE_DIRECTORY ${_doc})
  file(CONFIGURE OUTPUT ${_doc}/changelog CONTENT
"${_pkg} (${PITMAP_PACKAGE_VERSION}) unstable; urgency=medium

  * Built with CPack from ${_commit} (docs/packages.md).

 -- ${CPACK_PACKAGE_CONTACT}  ${_changelog_date}
" @ONLY)
  file(ARCHIVE_CREATE OUTPUT ${_doc}/changelog.gz PATHS ${_doc}/changelog FORMAT raw
       COMPRESSION GZip COMPRESSION_LEVEL 9)
  install(FILES ${CMAKE_CURRENT_LIST_DIR}/debian/copyright ${_doc}/changelog.gz
          DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/doc/${_pkg} COMPONENT ${_comp})
endforeach()

# pitmap-acqd (component acqd).
set(CPACK_COMPONENT_ACQD_DISPLAY_NAME "pitmap-acqd")
set(CPACK_DEBIAN_ACQD_PACKAGE_NAME pitmap-acqd)
# Extended descriptions: lines of at most 79 characters (CPack indents them by one).
set(CPACK_DEBIAN_ACQD_DESCRIPTION
    "onboard acquisition daemon of pitmap (sonar and GNSS/INS to GPS-timed logs)
pitmap-acqd reads the NovAtel SPAN receiver (serial, TCP) and the Imagenex
Delta T multibeam (UDP), stamps everything in GPS time, writes rotated LCM
logs and publishes them on LCM. A sandboxed systemd service (user pitmap, no
capabilities) with its sysusers.d, tmpfiles.d and sysctl.d snippets.
Configuration: /etc/pitmap/acqd.yaml (example: /etc/pitmap/acqd.yaml.example).")
# systemd-sysusers/systemd-tmpfiles when there (the vehicle); the postinst falls back to
# useradd and install -d (passwd, coreutils) in a container without systemd.
set(CPACK_DEBIAN_ACQD_PACKAGE_RECOMMENDS "systemd")
if(_shlibs_depends)
  string(SUBSTRING "${_shlibs_depends}" 2 -1 CPACK_DEBIAN_ACQD_PACKAGE_DEPENDS)
endif()
_pitmap_control_files(pitmap-acqd CPACK_DEBIAN_ACQD_PACKAGE_CONTROL_EXTRA)

# pitmap (component shore).
set(CPACK_COMPONENT_SHORE_DISPLAY_NAME "pitmap")
set(CPACK_DEBIAN_SHORE_PACKAGE_NAME pitmap)
set(CPACK_DEBIAN_SHORE_DESCRIPTION
    "shore processor of pitmap: flooded open-pit mine maps from survey logs
pitmap turns the logs of pitmap-acqd into calibrated, SLAM-corrected
soundings, a mesh, grids and an HTML report (pitmap run); pitmap live shows
coverage and alarms during a survey, pitmap edit cleans soundings by hand.
Also pitmap-sim (synthetic surveys), pitmap-eval (scores against ground
truth), pitmap-inspect (log contents) and pitmap-campaign (many surveys as a
Snakemake workflow, on one machine or a Slurm cluster).")
# What dpkg-shlibdeps cannot see: pitmap-report's Python modules (python3-yaml: its equipment
# file), and three.js read at run time
# by the report's 3D view and the edit page (/usr/share/javascript/three). python3-gdal: the
# report's sonar mosaic section and its grid coordinates only; libopenblas0-pthread: the fast
# BLAS under CHOLMOD (SLAM).
# snakemake: pitmap-campaign's engine (a Recommends: ~190 Python packages that pitmap run and
# the report never load; pitmap-campaign says to install it when it is missing); python3-yaml:
# pitmap-campaign reads the campaign file with it, also for `check` without snakemake.
set(CPACK_DEBIAN_SHORE_PACKAGE_DEPENDS
    "python3, python3-numpy, python3-matplotlib, python3-yaml, libjs-three${_shlibs_depends}")
set(CPACK_DEBIAN_SHORE_PACKAGE_RECOMMENDS "python3-gdal, libopenblas0-pthread, snakemake")
# chromium: pitmap-report --pdf prints the report through it (pitmap_report_lib/cdp.py).
set(CPACK_DEBIAN_SHORE_PACKAGE_SUGGESTS "chromium")
_pitmap_control_files(pitmap CPACK_DEBIAN_SHORE_PACKAGE_CONTROL_EXTRA)

include(CPack)
