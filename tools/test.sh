#!/usr/bin/env bash
# One command: install dependencies, build, and pass every test (this is what CI runs).
# Both builds treat compiler warnings as errors (LUMEN_WERROR=ON; the option is off for ordinary builds).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
"$root/tools/setup.sh"
# tools/build.sh's build (build/, Release with debug info), with -Werror.
cmake -S "$root" -B "$root/build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLUMEN_WERROR=ON >/dev/null
cmake --build "$root/build" -j"$(nproc)"
(cd "$root/build" && ctest --output-on-failure -j"$(nproc)")
# Same unit tests under AddressSanitizer + UndefinedBehaviorSanitizer (scene-level tests are long, run only in Release).
cmake -S "$root" -B "$root/build-asan" -DCMAKE_BUILD_TYPE=Debug -DLUMEN_SANITIZE=ON -DLUMEN_WERROR=ON >/dev/null
cmake --build "$root/build-asan" -j"$(nproc)"
(cd "$root/build-asan" && ctest --output-on-failure -j"$(nproc)" -L unit)
