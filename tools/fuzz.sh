#!/usr/bin/env bash
# libFuzzer over every file reader (tests/fuzz/readers.hpp), a fixed time each from a fixed seed: the bounded run
# CI makes (tools/test.sh). BUILD is a sanitizer build configured with -DLUMEN_FUZZ=ON (clang).
#   tools/fuzz.sh BUILD [SECONDS]  SECONDS per reader (default 10); LUMEN_FUZZ_READERS="scene obj" for some
# Two readers run at a time. The surface readers run assimp in a child process per input (engine/isolated.hpp), so
# they try tens of inputs a second where the others try thousands.
# Each reader starts from a copy of its kept inputs, tests/fuzz/inputs/<reader>/, but the endless ones (timeout-*),
# in a scratch folder (what the run adds to the corpus goes there too). A finding (crash, sanitizer report, leak, exhausted memory, timeout, or an exception the
# reader does not document) is copied to tests/fuzz/inputs/<reader>/ under libFuzzer's name and printed in base64;
# the script exits 1. Fix the reader and commit the input: FuzzInputs.KeptBadInputsAreRefusedNamingTheFile then
# replays it in both of CI's builds.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:?usage: tools/fuzz.sh BUILD [SECONDS]}"
seconds="${2:-10}"
fuzzer="$build/lumen_fuzz"
[ -x "$fuzzer" ] || { echo "tools/fuzz.sh: $fuzzer: no such program (configure $build with -DLUMEN_FUZZ=ON)" >&2; exit 2; }
readers="${LUMEN_FUZZ_READERS:-scene centreline obj stl ply off msh vtu vtk replay pose ccd}"
scratch="$(mktemp -d "${TMPDIR:-/tmp}/lumen_fuzz_run_XXXXXX")"
trap 'rm -rf "$scratch"' EXIT
# Limits: one input may take 10 s and allocate 1 GiB at once (a 50,000-tet organ's files need a few tens of MiB).
fuzz_one() {
  local reader="$1" corpus="$scratch/$1"
  mkdir -p "$corpus"
  # The kept inputs but the endless ones (each of their mutations would cost the run a timeout).
  find "$root/tests/fuzz/inputs/$reader" -maxdepth 1 -type f ! -name 'timeout-*' -exec cp {} "$corpus/" \;
  local start=$SECONDS
  if LUMEN_FUZZ_READER="$reader" "$fuzzer" -max_total_time="$seconds" -seed=1 -timeout=10 -malloc_limit_mb=1024 \
       -rss_limit_mb=3072 -print_final_stats=1 -artifact_prefix="$corpus/" \
       "$corpus" >"$scratch/$reader.log" 2>&1; then
    echo "$reader: $(grep -Eo 'stat::number_of_executed_units: *[0-9]+' "$scratch/$reader.log" | grep -Eo '[0-9]+$') inputs," \
         "$(grep -Eo 'cov: [0-9]+' "$scratch/$reader.log" | tail -1 | grep -Eo '[0-9]+') edges, no finding" \
         "in $((SECONDS - start)) s"
    return 0
  fi
  echo "=== $reader: FINDING ==="
  tail -n 60 "$scratch/$reader.log"
  for found in "$corpus"/crash-* "$corpus"/leak-* "$corpus"/oom-* "$corpus"/timeout-*; do
    [ -f "$found" ] || continue
    cp "$found" "$root/tests/fuzz/inputs/$reader/"
    echo "kept as tests/fuzz/inputs/$reader/$(basename "$found"); base64:"
    base64 "$found"
  done
  return 1
}
export -f fuzz_one
export root scratch fuzzer seconds
# Two readers at a time (CI's machines have 2 cores); every reader runs even after a finding.
status=0
printf '%s\n' $readers | xargs -P "$(nproc)" -I{} bash -c 'fuzz_one "$@"' _ {} || status=1
exit $status
