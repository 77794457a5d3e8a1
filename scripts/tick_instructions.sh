#!/usr/bin/env bash
# Instructions per runtime tick (README, Performance -> Runtime): callgrind counts of
# build/runtime_ticks (tests/bench/runtime_ticks.cc: the runtime benchmark's ticks) at 1300 and
# at 300 ticks, their difference over 1000, for drag and poke + mesh, quasi-static and dynamic,
# at 50, 100 and 200 segments. Unlike times on a shared machine the counts repeat exactly.
#   scripts/tick_instructions.sh [path/to/runtime_ticks]
set -euo pipefail
cd "$(dirname "$0")/.."
ticks_bin="${1:-build/runtime_ticks}"
[[ -x "$ticks_bin" ]] || { echo "tick_instructions.sh: no $ticks_bin (cmake --build build --target runtime_ticks)" >&2; exit 1; }
command -v valgrind >/dev/null || { echo "tick_instructions.sh: needs valgrind" >&2; exit 1; }
count() {  # instructions of one run
  valgrind --tool=callgrind --callgrind-out-file=/dev/null "$ticks_bin" "$@" 2>&1 |
    awk '/Collected/ {print $4}'
}
printf '%-22s %8s %16s  %s\n' tick segments instructions "last run"
for poke in 0 1; do
  for dynamic in 0 1; do
    for segments in 50 100 200; do
      a=$(count "$segments" 300 "$dynamic" "$poke")
      b=$(count "$segments" 1300 "$dynamic" "$poke")
      kind=$([[ $poke == 1 ]] && echo "poke+mesh" || echo "drag")
      mode=$([[ $dynamic == 1 ]] && echo "dynamic" || echo "quasi-static")
      printf '%-22s %8d %16d  %s\n' "$kind $mode" "$segments" $(((b - a) / 1000)) \
        "$("$ticks_bin" "$segments" 1300 "$dynamic" "$poke")"
    done
  done
done
