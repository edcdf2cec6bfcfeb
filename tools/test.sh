#!/usr/bin/env bash
# One command: install dependencies, build, and pass every test (this is what CI runs).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
"$root/tools/setup.sh"
"$root/tools/build.sh"
(cd "$root/build" && ctest --output-on-failure -j"$(nproc)")
# Same unit tests under AddressSanitizer + UndefinedBehaviorSanitizer (scene-level tests are long, run only in Release).
cmake -S "$root" -B "$root/build-asan" -DCMAKE_BUILD_TYPE=Debug -DLUMEN_SANITIZE=ON >/dev/null
cmake --build "$root/build-asan" -j"$(nproc)"
(cd "$root/build-asan" && ctest --output-on-failure -j"$(nproc)" -L unit)
