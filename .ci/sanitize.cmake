# SPDX-License-Identifier: MIT
# Initial cache (cmake -C) of the CI sanitizer + fuzzer build (.ci/run stage 3): RelWithDebInfo
# with line tables only instead of full debug info. Sanitizer and libFuzzer stack traces keep
# function, file and line; nobody steps through this build in a debugger.
# -O1, the level the AddressSanitizer documentation recommends, instead of -O2: the compile is
# the stage's largest cost (tests/processor/registration/registration_test.cpp: 47.8 -> 38.6 CPU
# s with clang 14) and the instrumented code inlines less, so reports point closer to the line.
set(CMAKE_C_FLAGS_RELWITHDEBINFO "-O1 -gline-tables-only -DNDEBUG" CACHE STRING "")
set(CMAKE_CXX_FLAGS_RELWITHDEBINFO "-O1 -gline-tables-only -DNDEBUG" CACHE STRING "")
