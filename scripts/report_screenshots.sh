#!/usr/bin/env bash
# Screenshots of every bundled recipe's report and of the bench page, taken with headless
# Chromium (Debian's `chromium`: bash scripts/install_deps.sh --tests) after the page's 3-D views
# are drawn: the static suture cantilever, the tissue drag and poke, the moving suture swing, a
# rollout of the cable recording (with --fit) and `rodfit bench --quick`. Writes the reports into
# out/ and the pictures into out/screenshots/; with --docs also the two the docs link
# (docs/images/report_suture.png, docs/images/report_tissue_drag.png). Needs build/rodfit.
set -euo pipefail
cd "$(dirname "$0")/.."
command -v chromium >/dev/null || { echo "needs chromium (bash scripts/install_deps.sh --tests)" >&2; exit 1; }
docs=0
if [ "${1:-}" = "--docs" ]; then docs=1; fi
mkdir -p out/screenshots
profile="$(mktemp -d)"
trap 'rm -rf "$profile"' EXIT
shot() {  # shot PAGE OUT.png HEIGHT
  # The flags keep Chromium off the network and out of the user's profile; WebGL runs on
  # SwiftShader (software), which headless needs without a GPU; the virtual time lets the 3-D
  # views finish drawing before the picture. The window is 1400 px wide, as a lab's monitor.
  chromium --headless --no-sandbox --disable-gpu --enable-unsafe-swiftshader --disable-quic \
      --no-first-run --disable-background-networking --disable-component-update --disable-sync \
      --user-data-dir="$profile" --hide-scrollbars --window-size=1400,"$3" \
      --virtual-time-budget=20000 --screenshot="$2" "file://$PWD/$1" >/dev/null 2>&1
  echo "wrote $2"
}
fit() {  # fit EXPERIMENT NAME
  build/rodfit fit "$1" -o "out/$2_profile.json" --report "out/$2_report" -q || [ $? -eq 4 ]
}
fit calibration/suture_cantilever/experiment.yaml suture
fit calibration/tissue_drag/experiment.yaml tissue_drag
fit calibration/tissue_poke/experiment.yaml tissue_poke
fit data/suture_swing_fit/experiment.yaml swing
# A rollout: the cable's own recording (10 markers, 1 mm noise, 2 % dropped), stiffness and
# drag fitted to it (about 30 s).
build/rodfit simulate data/scenes/cable_drive.yaml -o out/cable --markers 10 --marker-noise 0.001 \
    --marker-drop 0.02 --seed 1 >/dev/null
build/rodfit rollout data/scenes/cable_drive.yaml out/cable/markers.csv -o out/cable_rollout \
    --fit bend_stiffness,damping --marker-sigma 0.001 --report out/cable_rollout_report -q >/dev/null
build/rodfit bench --quick -o out/bench >/dev/null
shot out/suture_report/index.html out/screenshots/report_suture.png 4400
shot out/tissue_drag_report/index.html out/screenshots/report_tissue_drag.png 5600
shot out/tissue_poke_report/index.html out/screenshots/report_tissue_poke.png 3800
shot out/swing_report/index.html out/screenshots/report_swing.png 3600
shot out/cable_rollout_report/index.html out/screenshots/report_rollout.png 2600
shot out/bench/index.html out/screenshots/bench.png 6000
if [ "$docs" = 1 ]; then
  shot out/suture_report/index.html docs/images/report_suture.png 2000
  shot out/tissue_drag_report/index.html docs/images/report_tissue_drag.png 3300
fi
