# SPDX-License-Identifier: MIT
# Initial cache (cmake -C) of the CI sanitizer + fuzzer build (.ci/run stage 3): RelWithDebInfo
# with line tables only instead of full debug info. Sanitizer and libFuzzer stack traces keep
# function, file and line; nobody steps through this build in a debugger.
set(CMAKE_C_FLAGS_RELWITHDEBINFO "-O2 -gline-tables-only -DNDEBUG" CACHE STRING "")
set(CMAKE_CXX_FLAGS_RELWITHDEBINFO "-O2 -gline-tables-only -DNDEBUG" CACHE STRING "")
