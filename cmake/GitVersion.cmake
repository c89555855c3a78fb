# SPDX-License-Identifier: MIT
# Writes the version source (common/version_info.cpp.in -> OUTPUT) with the project version and
# the git commit of SOURCE_DIR. Run as a script (cmake -P) at configure time and before every
# build; configure_file rewrites OUTPUT only when its text changes, so an unchanged commit
# recompiles nothing.
#   -DSOURCE_DIR= -DTEMPLATE= -DOUTPUT= -DPITMAP_VERSION= [-DGIT_EXECUTABLE=]
#   [-DCOMMIT_OVERRIDE=]  (a packager's fixed commit; "unknown" when not a checkout)
set(PITMAP_COMMIT "unknown")
if(COMMIT_OVERRIDE)
  set(PITMAP_COMMIT "${COMMIT_OVERRIDE}")
elseif(GIT_EXECUTABLE)
  # Only this repository's own commit: a source tarball unpacked inside another checkout (a
  # packaging tree) is "unknown", not that checkout's commit.
  execute_process(
    COMMAND ${GIT_EXECUTABLE} -C ${SOURCE_DIR} rev-parse --show-toplevel
    RESULT_VARIABLE _rc OUTPUT_VARIABLE _top ERROR_QUIET OUTPUT_STRIP_TRAILING_WHITESPACE)
  if(_rc EQUAL 0)
    get_filename_component(_top "${_top}" REALPATH)
    get_filename_component(_src "${SOURCE_DIR}" REALPATH)
  endif()
  if(_rc EQUAL 0 AND _top STREQUAL _src)
    execute_process(
      COMMAND ${GIT_EXECUTABLE} -C ${SOURCE_DIR} rev-parse --short=12 HEAD
      RESULT_VARIABLE _rc OUTPUT_VARIABLE _commit ERROR_QUIET OUTPUT_STRIP_TRAILING_WHITESPACE)
    if(_rc EQUAL 0 AND _commit)
      set(PITMAP_COMMIT "${_commit}")
      execute_process(
        COMMAND ${GIT_EXECUTABLE} -C ${SOURCE_DIR} status --porcelain --untracked-files=no
        RESULT_VARIABLE _rc OUTPUT_VARIABLE _changes ERROR_QUIET)
      if(_rc EQUAL 0 AND NOT _changes STREQUAL "")
        string(APPEND PITMAP_COMMIT "-dirty")
      endif()
    endif()
  endif()
endif()
configure_file(${TEMPLATE} ${OUTPUT} @ONLY)
