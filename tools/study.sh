#!/usr/bin/env bash
# Speed-against-error study in one command: installs what it needs, builds, runs the sweep (about 40 min on
# 2 cores) and writes docs/study.csv, docs/study_load.csv, docs/study_capacity.csv and the plot docs/study.png.
# Extra arguments go to lumen_study (e.g. --quick, --max-level 2, --no-render).
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
if ! /usr/bin/python3 -c "import matplotlib" 2>/dev/null; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -q && $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -q python3-matplotlib
fi
bash tools/build.sh
OUT="${LUMEN_STUDY_OUT:-docs}"
build/lumen_study --out "$OUT/study.csv" --load-out "$OUT/study_load.csv" --capacity-out "$OUT/study_capacity.csv" "$@"
/usr/bin/python3 tools/study_plot.py "$OUT/study.csv" "$OUT/study.png"
echo "wrote $OUT/study.csv $OUT/study_load.csv $OUT/study_capacity.csv $OUT/study.png"
