# SPDX-License-Identifier: MIT
# Initial cache (cmake -C) of the CI sanitizer + fuzzer build (.ci/run stage 4): RelWithDebInfo
# with line tables only instead of full debug info. Sanitizer and libFuzzer stack traces keep
# function, file and line; nobody steps through this build in a debugger.
# -O1, the level the AddressSanitizer documentation recommends, instead of -O2: the compile is
# the stage's largest cost (tests/processor/registration/registration_test.cpp: 47.8 -> 38.6 CPU
# s with clang 14) and the instrumented code inlines less, so reports point closer to the line.
set(CMAKE_C_FLAGS_RELWITHDEBINFO "-O1 -gline-tables-only -DNDEBUG" CACHE STRING "")
set(CMAKE_CXX_FLAGS_RELWITHDEBINFO "-O1 -gline-tables-only -DNDEBUG" CACHE STRING "")
# Two of UBSan's checks are left out (PITMAP_SANITIZE_EXCLUDE, after -fsanitize= on every compile
# line, the fuzz targets' included). object-size: AddressSanitizer already finds every access
# outside an object, on the heap, the stack and in globals, where object-size sees only the sizes
# the optimiser can prove. alignment: the code reads outside bytes byte by byte or with memcpy,
# never through a cast pointer (no reinterpret_cast of a buffer to a wider type), and x86
# tolerates a misaligned access anyway. The two are a third to a half of what UBSan adds to the
# compile (clang 14, -O1, CPU s: processor/fusion/tsdf.cpp 55.4 -> 49.2, registration_test.cpp
# 44.6 -> 35.0; with ASan alone 36.8 and 26.4).
set(PITMAP_SANITIZE_EXCLUDE "object-size,alignment" CACHE STRING "")
# LLVM's linker: an instrumented test executable links in a third of GNU ld's CPU time (the
# adapters test: 1.2 instead of 3.2 CPU s), and the stage links about 120 of them.
set(CMAKE_EXE_LINKER_FLAGS "-fuse-ld=lld" CACHE STRING "")
