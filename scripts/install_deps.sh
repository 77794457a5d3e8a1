#!/usr/bin/env bash
# Installs what rodfit builds against, only what is missing: Debian packages (apt-get), the
# report's 3-D plotting library (plotly.js's gl3d bundle, from the npm registry) and the npm
# package one test uses (MuJoCo's WebAssembly build); Debian's pybind11, numpy, pytest and
# matplotlib for the Python package. With --tests,
# also what the test suite needs beyond the build: Debian's `chromium`, in which the report test
# loads every report headless (tests/report/report_browser_test.cc).
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
  # The Python package (docs/python.md): pybind11 and Python's headers to build it, numpy for its
  # arrays, pytest for its tests, matplotlib for its example's plot.
  pybind11-dev python3-dev python3-numpy python3-pytest python3-matplotlib
)
if [ "${1:-}" = "--tests" ]; then packages+=(chromium); fi
# The report's interactive 3-D view (docs/formats.md, "Fit report") inlines plotly.js's gl3d
# bundle, a pinned version so that two machines write the same report. It is installed here,
# outside the repository (CMake's RODFIT_PLOTLY_JS finds it; the report is written without its
# 3-D view, with a warning, where it is missing).
plotly_package="plotly.js-gl3d-dist-min"
plotly_version="4.1.1"
plotly_prefix="/usr/local/share/rodfit"
plotly_file="$plotly_prefix/node_modules/$plotly_package/plotly-gl3d.min.js"
plotly_installed() {
  [ -f "$plotly_file" ] &&
    grep -q "\"version\": *\"$plotly_version\"" "$plotly_prefix/node_modules/$plotly_package/package.json"
}
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# npm, Debian's, only when the machine has none (a Node.js from elsewhere brings its own).
if ! plotly_installed && ! command -v npm >/dev/null 2>&1; then missing+=(npm); fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
if [ ${#missing[@]} -gt 0 ]; then
  echo "install_deps: installing ${missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
if ! plotly_installed; then
  echo "install_deps: installing $plotly_package@$plotly_version (npm) into $plotly_prefix" >&2
  $SUDO mkdir -p "$plotly_prefix"
  $SUDO npm install --prefix "$plotly_prefix" --no-save --no-package-lock --no-audit --no-fund \
    --loglevel=error "$plotly_package@$plotly_version" >/dev/null
  plotly_installed || { echo "install_deps: $plotly_file missing after npm install" >&2; exit 1; }
fi
# npm: MuJoCo's WebAssembly build for the test that loads the MuJoCo export
# (tests/export/package.json, package-lock.json), when the machine has node and npm; without them
# that test is skipped. Only installed once (node_modules kept).
export_tests="$(cd "$(dirname "$0")/.." && pwd)/tests/export"
if command -v npm >/dev/null 2>&1 && [ ! -d "$export_tests/node_modules/mujoco-js" ]; then
  echo "install_deps: npm ci in tests/export (mujoco-js)" >&2
  npm ci --prefix "$export_tests" --no-audit --no-fund >/dev/null
fi
