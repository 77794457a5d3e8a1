#!/usr/bin/env bash
# The main job on the bundled data: build the CLI only (not the tests, benchmarks or examples:
# scripts/test.sh builds those), then fit the suture cantilever recipe
# (calibration/suture_cantilever) and write the profile and its report into out/.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/build.sh rodfit-cli
build/rodfit fit calibration/suture_cantilever/experiment.yaml -o out/suture_profile.json \
    --report out/suture_report
echo "wrote out/suture_profile.json and out/suture_report/"
