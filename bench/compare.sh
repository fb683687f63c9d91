#!/usr/bin/env bash
# Two builds of mrdrive side by side on one machine: the closed loop's real-time factor
# (RA at 1.0x and 0.75x on Town01 route 0 with 5 vehicles + 10 pedestrians, seed 0, and
# the default scenario), interleaved three rounds, one line per run, then the medians.
#
#   bench/compare.sh BEFORE_BINARY AFTER_BINARY
#
# Build the "before" binary from a worktree with its own target folder (two worktrees
# sharing one target folder overwrite each other's crates of the same name):
#   git worktree add /tmp/before COMMIT && (cd /tmp/before && CARGO_TARGET_DIR=/tmp/before-target cargo build --release)
set -euo pipefail
cd "$(dirname "$0")/.."
before=$1; after=$2
runs=(
  "town01 RA 1.0x|scenarios/paper/town01_route0.toml --checkpoint models/ra.safetensors --scale 1.0 --vehicles 5 --pedestrians 10 --seed 0"
  "town01 RA 0.75x|scenarios/paper/town01_route0.toml --checkpoint models/ra.safetensors --scale 0.75 --vehicles 5 --pedestrians 10 --seed 0"
  "default scenario|scenarios/default.toml"
)
out=$(mktemp -d)
for round in 1 2 3; do
  for r in "${runs[@]}"; do
    name=${r%%|*}; args=${r#*|}
    for which in before after; do
      bin=$before; [ "$which" = after ] && bin=$after
      # shellcheck disable=SC2086
      "$bin" run $args --quiet --no-picture --json "$out/$which.json" > /dev/null
      python3 - "$out/$which.json" "$round" "$name" "$which" <<'PY' | tee -a "$out/lines.txt"
import json, sys
r = json.load(open(sys.argv[1])); p = r["perf"]; res = r["result"]
print(f"{sys.argv[2]}|{sys.argv[3]}|{sys.argv[4]}|{p['real_time_factor']:.2f}|{p['wall_s']:.2f}|{p['render_s']:.2f}|{p['driver_s']:.2f}|{res['ticks']}")
PY
    done
  done
done
python3 - "$out/lines.txt" <<'PY'
import sys, statistics, collections
rows = collections.defaultdict(list)
for line in open(sys.argv[1]):
    _, name, which, rtf, wall, render, driver, _ = line.strip().split("|")
    rows[(name, which)].append((float(rtf), float(render), float(driver)))
print("| run | before: real-time factor (render s, driver s) | after | ratio |")
print("| --- | --- | --- | --- |")
for name in dict.fromkeys(n for n, _ in rows):
    med = {w: [statistics.median(x[i] for x in rows[(name, w)]) for i in range(3)] for w in ("before", "after")}
    b, a = med["before"], med["after"]
    print(f"| {name} | {b[0]:.2f} ({b[1]:.1f}, {b[2]:.1f}) | {a[0]:.2f} ({a[1]:.1f}, {a[2]:.1f}) | {a[0] / b[0]:.2f} |")
PY
