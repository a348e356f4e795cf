#!/usr/bin/env bash
# Quick start, step 1: install the Debian 12 packages (libsep-dev: metadetection's detection; clang: the fuzz targets; pybind11 and numpy:
# the Python module; matplotlib: its diagnostics report; OpenMPI: the MPI driver), build in
# Release, run the demo fit.
set -euo pipefail
cd "$(dirname "$0")/.."
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends \
  g++ cmake make pkg-config libtbb-dev libfftw3-dev libeigen3-dev libxsimd-dev libcfitsio-dev zlib1g-dev libsep-dev \
  libgtest-dev googletest libbenchmark-dev clang libclang-rt-14-dev \
  pybind11-dev python3-dev python3-numpy python3-pytest python3-matplotlib libopenmpi-dev openmpi-bin >/dev/null
# Debian's interpreter, the one python3-numpy serves (a pyenv or venv python3 earlier on PATH has not).
# Benchmarks are built by bench/run in a build of their own (build-bench): not needed here.
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DPython_EXECUTABLE=/usr/bin/python3 -DSTAMPEDE_BUILD_BENCH=OFF >/dev/null
cmake --build build -j"$(nproc)"
./build/tools/stampede demo
