#!/usr/bin/env bash
# One command: install dependencies, build, and pass every test (this is what CI runs).
# Both builds treat compiler warnings as errors (LUMEN_WERROR=ON; the option is off for ordinary builds).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
"$root/tools/setup.sh"
# Debug information as line tables only (-g1): backtraces and sanitizer reports keep file:line, and the compiler
# spends a third to nearly half less time per file than with full -g (variables and types, which CI never reads).
line_tables=-g1
# Both builds are unity builds (CMake joins up to 8 sources of a target into one translation unit): Eigen, gtest and
# the JSON library are parsed and their templates instantiated once per batch instead of once per file. Measured
# from scratch on 2 cores (CPU = user + sys): this Release build 666 s of CPU and 347 s wall against 1068 s and
# 545 s per file; the sanitizer build 696 s of CPU and 373 s wall against 1092 s. So a name local to one source
# file (an anonymous namespace) must not be another file's of the same target: shared helpers live in
# physics/detail/, collision/detail/ or tests/support/.
unity="-DCMAKE_UNITY_BUILD=ON"
# Both link with LLVM's lld (package lld): a test program's link 0.5 s against 3.4 s with GNU ld (test_engine,
# Release, measured once each way); about twenty programs are linked per run.
lld="-DCMAKE_EXE_LINKER_FLAGS=-fuse-ld=lld -DCMAKE_SHARED_LINKER_FLAGS=-fuse-ld=lld"
# tools/build.sh's build (build/, Release with debug info), every target, with -Werror.
cmake -S "$root" -B "$root/build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLUMEN_WERROR=ON $unity $lld \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 $line_tables -DNDEBUG" >/dev/null
cmake --build "$root/build" -j"$(nproc)"
(cd "$root/build" && ctest --output-on-failure -j"$(nproc)")
# Same unit tests under AddressSanitizer + UndefinedBehaviorSanitizer (scene-level tests are long, run only in
# Release): only the programs `ctest -L unit` runs (target lumen_unit_tests), no benchmarks. Compiled by clang: a
# second compiler's warnings (also errors), and about 28 % less CPU than GCC for this build (measured from scratch:
# 1092 s against 1510 s). A tree configured earlier with another compiler is configured afresh.
if [ -f "$root/build-asan/CMakeCache.txt" ] && ! grep -q '^CMAKE_CXX_COMPILER:[A-Z]*=.*clang++' "$root/build-asan/CMakeCache.txt"; then
  rm -rf "$root/build-asan"
fi
# The same tree carries libFuzzer's coverage (LUMEN_FUZZ) and builds the fuzz target, lumen_fuzz.
cmake -S "$root" -B "$root/build-asan" -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_BUILD_TYPE=Debug -DLUMEN_SANITIZE=ON -DLUMEN_FUZZ=ON -DLUMEN_WERROR=ON $unity $lld \
  -DLUMEN_BUILD_BENCHMARKS=OFF -DCMAKE_CXX_FLAGS_DEBUG="$line_tables" >/dev/null
cmake --build "$root/build-asan" -j"$(nproc)" --target lumen_unit_tests lumen_fuzz
(cd "$root/build-asan" && ctest --output-on-failure -j"$(nproc)" -L unit)
# Every file reader fuzzed for a bounded time (4 s each, two at a time: about half a minute); a finding fails the run.
"$root/tools/fuzz.sh" "$root/build-asan" 4
