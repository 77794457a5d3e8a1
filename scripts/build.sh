#!/usr/bin/env bash
# Installs what is missing, then configures and builds rodfit (Release) in ./build: every target,
# or only the targets given (scripts/quickstart.sh builds just the CLI, `rodfit-cli`).
# Idempotent: re-running rebuilds only what changed.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install_deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
if [ $# -gt 0 ]; then
  for target in "$@"; do cmake --build build --target "$target" -j"$(nproc)"; done
else
  cmake --build build -j"$(nproc)"
fi
