#!/usr/bin/env bash
# Installs the Debian packages rodfit builds against, only those that are missing, and the npm
# package one test uses.
# Idempotent: a machine that has them all is left untouched (no apt-get update either).
set -euo pipefail
packages=(
  build-essential cmake pkg-config
  libeigen3-dev libceres-dev libgoogle-glog-dev libnlopt-cxx-dev libyaml-cpp-dev nlohmann-json3-dev
  libcli11-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  # LAPACK: the tests cross-check the banded factorisations against dpbtrf / dgbtrf.
  liblapack-dev
  # OpenCV: only the modules rodfit uses (core, imgproc, calib3d), not the metapackage; imgcodecs
  # for the tests only (an independent image decoder). Image files: libpng, libjpeg, libtiff.
  libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev libopencv-calib3d-dev
  libpng-dev libjpeg-dev libtiff-dev
)
# npm: MuJoCo's WebAssembly build for the test that loads the MuJoCo export
# (tests/export/package.json, package-lock.json), when the machine has node and npm; without them
# that test is skipped. Only installed once (node_modules kept).
export_tests="$(cd "$(dirname "$0")/.." && pwd)/tests/export"
if command -v npm >/dev/null 2>&1 && [ ! -d "$export_tests/node_modules/mujoco-js" ]; then
  echo "install_deps: npm ci in tests/export (mujoco-js)" >&2
  npm ci --prefix "$export_tests" --no-audit --no-fund >/dev/null
fi
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
echo "install_deps: installing ${missing[*]}" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
