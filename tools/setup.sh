#!/usr/bin/env bash
# Install the Debian packages Lumen builds and runs with (idempotent).
set -euo pipefail
# libopenblas0-pthread: OpenBLAS takes over Debian's libblas.so.3 alternative from the reference BLAS, for CHOLMOD's
# supernodal factorisations and solves (the threaded flavour is the one safe to call from two threads at once;
# physics/fem.cpp runs it on one thread a call). lld: tools/test.sh links with it (faster than GNU ld).
pkgs=(build-essential cmake pkg-config libeigen3-dev libsuitesparse-dev libopenblas0-pthread libosmesa6-dev
      libassimp-dev libexpat1-dev libpng-dev libavcodec-dev libavformat-dev libavutil-dev libswscale-dev
      nlohmann-json3-dev libcli11-dev libgtest-dev libgmock-dev libbenchmark-dev python3 python3-meshio python3-matplotlib
      calculix-ccx libopenigtlink-dev openigtlink-examples libnglib-dev libgmsh-dev libcgal-dev clang libclang-rt-dev lld)
missing=()
for p in "${pkgs[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y "${missing[@]}"
fi
