#!/usr/bin/env bash
# Regenerates the README's report screenshots (docs/images/report_*.png): fits the suture and the
# tissue drag recipes with --report into out/ and photographs each index.html with headless
# Chromium (Debian's `chromium` package: `apt-get install chromium`). Needs build/rodfit.
set -euo pipefail
cd "$(dirname "$0")/.."
command -v chromium >/dev/null || { echo "needs chromium (apt-get install chromium)" >&2; exit 1; }
mkdir -p out docs/images
profile="$(mktemp -d)"
trap 'rm -rf "$profile"' EXIT
shot() {  # shot REPORT_DIR OUT.png HEIGHT
  # The flags keep Chromium off the network (this machine has none) and out of the user's
  # profile; the window is 1400 px wide, as a lab's monitor.
  chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
      --disable-background-networking --disable-component-update --disable-sync \
      --user-data-dir="$profile" --hide-scrollbars --window-size=1400,"$3" \
      --screenshot="$2" "file://$PWD/$1/index.html" >/dev/null 2>&1
  echo "wrote $2"
}
build/rodfit fit calibration/suture_cantilever/experiment.yaml -o out/suture_profile.json \
    --report out/suture_report -q
build/rodfit fit calibration/tissue_drag/experiment.yaml -o out/tissue_drag_profile.json \
    --report out/tissue_drag_report -q
shot out/suture_report docs/images/report_suture.png 2000
shot out/tissue_drag_report docs/images/report_tissue_drag.png 3300
