#!/usr/bin/env bash
# Identification of a 1,000,000-row measurement CSV (issues 18/19): wall time, CPU time and
# peak memory from /usr/bin/time -v, for
#   dense:  the paper's indexing campaign at a 0.003212° pitch (1,000,000 measured stops, 17 h
#           of robot time), measured in a tracker frame, identified without a target;
#   poses:  1,000,000 scattered poses over the workspace (a whole cell's worth of path data),
#           measured in the base frame.
# Usage: scripts/bench_identify.sh [WORKDIR]      (default /tmp/robopost-bench-identify)
set -euo pipefail
cd "$(dirname "$0")/.."
W=${1:-/tmp/robopost-bench-identify}
BIN=target/dist/robopost  # the packaged build (Cargo.toml: profile.dist)
[ -n "${NO_BUILD:-}" ] || cargo build --profile dist --quiet
mkdir -p "$W"
if [ ! -f "$W/dense.csv" ]; then
  $BIN simulate truth --seed 19 --tracker 2800,1200,-300,-140,0.3,0.5 -o "$W/truth-tracker.json"
  python3 - "$W/dense.json" <<'PY'
import json, sys
ref = [0, -60, 100, 0, 45, 0]
pitch = 0.003212  # 2 x 1606 degrees of sweep / pitch = 1,000,000 measured stops
def test(axis, lo, hi, repeat=None):
    t = {"axis": axis, "from_deg": lo, "to_deg": hi, "pitch_deg": pitch, "reference_deg": ref}
    if repeat:
        t["repeat"] = {"axis": repeat[0], "angles_deg": repeat[1]}
    return t
tests = [test(1, -60, 60), test(2, -112, -19, (3, [58, 105, 153])),
         test(3, 10, 155, (2, [-112, -65, -19])), test(4, -90, 90), test(5, -116, 116),
         test(6, -180, 180)]
json.dump({"tests": tests, "dwell_s": 0.06, "axis_speed_deg_s": 30}, open(sys.argv[1], "w"))
PY
  $BIN simulate campaign --truth "$W/truth-tracker.json" --campaign "$W/dense.json" -o "$W/dense.csv"
fi
if [ ! -f "$W/poses.csv" ]; then
  $BIN simulate truth --seed 21 -o "$W/truth-base.json"
  python3 - "$W/poses-in.csv" <<'PY'
import random, sys
random.seed(7)
ranges = [(-60, 60), (-110, -20), (20, 150), (-90, 90), (-90, 90), (-180, 180)]
with open(sys.argv[1], "w") as f:
    f.write("test,a1,a2,a3,a4,a5,a6\n")
    for i in range(1_000_000):
        a = [random.uniform(lo, hi) for lo, hi in ranges]
        f.write("cell%d,%s\n" % (i // 100_000, ",".join("%.4f" % x for x in a)))
PY
  $BIN simulate poses --truth "$W/truth-base.json" --dwell 0.05 "$W/poses-in.csv" -o "$W/poses.csv"
fi
wc -l "$W/dense.csv" "$W/poses.csv"
run() {
  local name=$1; shift
  /usr/bin/time -v "$@" > "$W/$name.out" 2> "$W/$name.time" || true
  grep -E "Elapsed|User time|System time|Maximum resident" "$W/$name.time" | sed "s/^/$name: /"
  grep -E "^data:|^gross errors:|^noise floor|^  after" "$W/$name.out" | sed "s/^/$name: /"
}
run dense $BIN identify "$W/dense.csv" --frame tracker -o "$W/dense-cal.json"
run poses $BIN identify "$W/poses.csv" --effects 'geometric,map:A1..A6' --map-pitch 2 -o "$W/poses-cal.json"
