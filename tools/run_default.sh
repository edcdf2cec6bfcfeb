#!/usr/bin/env bash
# One command: install dependencies, build, and run the default scene into out/<scene name>/.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
"$root/tools/setup.sh"
"$root/tools/build.sh"
"$root/build/lumen" run "$root/scenes/paper-press.json" --out "$root/out/paper-press" "$@"
