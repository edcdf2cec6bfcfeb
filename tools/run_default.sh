#!/usr/bin/env bash
# One command: install dependencies, build, and run the default scene into out/<scene name>/.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
"$root/tools/setup.sh"
"$root/tools/build.sh"
# The default scene: the walls meeting, self-collision on (issue 9 will make it its accurate configuration once
# that runs at frame rate).
"$root/build/lumen" run "$root/scenes/full-closure-tet10.json" --out "$root/out/full-closure-tet10" "$@"
