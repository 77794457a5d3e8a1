#!/usr/bin/env bash
# A quick check that a build works end to end (5-15 s, against 25-49 min for the whole suite,
# scripts/test.sh): builds the CLI if needed (as the quickstart does), fits every bundled recipe
# with its report (each with its 3-D views), rolls out the cable recording with its report, runs
# the solver's stress suite (`rodfit bench --stress`: exit 1 on a wrong answer returned as
# success), and checks each run's exit status and outputs. Writes into out/smoke/. Exit 0 when
# all pass.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x build/rodfit ] || ./scripts/build.sh rodfit-cli
rm -rf out/smoke
mkdir -p out/smoke
failed=0
check() {  # check NAME COMMAND...: runs it, says ok or FAILED with its stderr
  local name="$1"
  shift
  if "$@" >"out/smoke/$name.out" 2>"out/smoke/$name.err"; then
    echo "ok      $name"
  else
    echo "FAILED  $name (exit $?):" >&2
    cat "out/smoke/$name.err" >&2
    failed=1
  fi
}
has() {  # has FILE TEXT: the file exists and holds the text
  grep -qF "$2" "$1"
}
for recipe in calibration/suture_cantilever calibration/tissue_drag calibration/tissue_poke \
              data/suture_swing_fit; do
  name="$(basename "$recipe")"
  check "fit_$name" build/rodfit fit "$recipe/experiment.yaml" -o "out/smoke/$name.json" \
      --report "out/smoke/${name}_report" -q
  check "report_$name" has "out/smoke/${name}_report/index.html" 'class="view3d"'
done
check simulate_cable build/rodfit simulate data/scenes/cable_drive.yaml -o out/smoke/cable \
    --markers 10
check rollout_cable build/rodfit rollout data/scenes/cable_drive.yaml out/smoke/cable/markers.csv \
    -o out/smoke/rollout --report out/smoke/rollout_report -q
check stress build/rodfit bench --stress -o out/smoke/bench
if [ "$failed" = 0 ]; then echo "smoke test passed (outputs in out/smoke/)"; fi
exit "$failed"
