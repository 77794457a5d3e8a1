#!/usr/bin/env bash
# Installs what is missing, then configures and builds rodfit (Release) in ./build: every target,
# or only the targets given (scripts/quickstart.sh builds just the CLI, `rodfit-cli`).
# Idempotent: re-running rebuilds only what changed.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install_deps.sh
# ccache, when the machine has it, makes a rebuild after a branch switch cheap; CI has none.
launcher=()
if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" >/dev/null
if [ $# -gt 0 ]; then
  for target in "$@"; do cmake --build build --target "$target" -j"$(nproc)"; done
else
  cmake --build build -j"$(nproc)"
fi
