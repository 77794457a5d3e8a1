#!/usr/bin/env bash
# The main job on the bundled data: build, then solve the bundled scene's cases and write
# out/cantilever/shapes.csv.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/build.sh
build/rodfit simulate data/scenes/cantilever.yaml -o out/cantilever
echo "wrote out/cantilever/shapes.csv"
