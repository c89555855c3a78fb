// SPDX-License-Identifier: MIT
// The precompiled header's own translation unit (tests/CMakeLists.txt, PITMAP_TEST_PCH).
int main() {
    return 0;
}
