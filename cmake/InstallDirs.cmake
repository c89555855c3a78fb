# SPDX-License-Identifier: MIT
# Where `cmake --install` and the Debian packages (cmake/Packaging.cmake, docs/packages.md) put
# things, relative to CMAKE_INSTALL_PREFIX (/usr for the packages, /usr/local by default). Two
# components: `acqd` (the vehicle package pitmap-acqd) and `shore` (the shore package pitmap).
include(GNUInstallDirs)
# The shore programs that find each other beside the running executable (pitmap runs
# pitmap-live and pitmap-report from its own folder, /proc/self/exe; pitmap-report reads
# pitmap_report_lib/, its viewer scripts and pitmap-ply-layout from its own folder): one
# private folder, with links in bin for the commands people type.
set(PITMAP_INSTALL_PROGRAMDIR "lib/pitmap" CACHE STRING
    "pitmap, pitmap-live, pitmap-report and what they load, relative to the prefix")
# systemd reads units, sysusers.d, tmpfiles.d and sysctl.d under /usr/lib and /usr/local/lib.
set(PITMAP_INSTALL_SYSTEMDDIR "lib" CACHE STRING
    "parent of systemd/system, sysusers.d, tmpfiles.d, sysctl.d, relative to the prefix")
# The daemon's unit reads /etc/pitmap/acqd.yaml whatever the prefix.
set(PITMAP_INSTALL_CONFIGDIR "/etc/pitmap" CACHE PATH "the daemon's configuration folder")

# pitmap_install_link(name): bin/<name> -> the program <name> of PITMAP_INSTALL_PROGRAMDIR, a
# relative symbolic link (component shore). The programs resolve it (/proc/self/exe,
# os.path.realpath) to find their siblings.
function(pitmap_install_link name)
  file(RELATIVE_PATH _rel ${CMAKE_INSTALL_FULL_BINDIR}
       ${CMAKE_INSTALL_PREFIX}/${PITMAP_INSTALL_PROGRAMDIR}/${name})
  set(_link ${CMAKE_BINARY_DIR}/install-links/${name})
  file(MAKE_DIRECTORY ${CMAKE_BINARY_DIR}/install-links)
  file(CREATE_LINK ${_rel} ${_link} SYMBOLIC)
  install(FILES ${_link} DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT shore)
endfunction()
