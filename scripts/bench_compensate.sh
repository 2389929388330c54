#!/usr/bin/env bash
# End-to-end compensation benchmark: a generated 1,000,000-point CAM program (smooth, with the
# hand-set calibration; and with the 10–60 µm Z ripple of a real CAM surface, with the
# calibration identified from the virtual robot's campaign) and a batch of 1000 programs x 1000
# points, each against `cp` of the same data as the floor.
# Wall time, CPU time and peak memory from /usr/bin/time -v. Usage:
#   scripts/bench_compensate.sh [WORKDIR]      (default /tmp/robopost-bench)
set -euo pipefail
cd "$(dirname "$0")/.."
W=${1:-/tmp/robopost-bench}
CAL=calibrations/kr30ha-handset.json
IDENTIFIED=calibrations/kr30ha-example.json
BIN=target/dist/robopost  # the packaged build (Cargo.toml: profile.dist)
[ -n "${NO_BUILD:-}" ] || cargo build --profile dist --quiet
mkdir -p "$W"
if [ ! -f "$W/cam1m.src" ]; then
  python3 fixtures/gen/cam_program.py milling "$W/cam1m.src" --points 1000000 >/dev/null
fi
if [ ! -f "$W/cam1m_ripple.src" ]; then
  python3 fixtures/gen/cam_program.py milling "$W/cam1m_ripple.src" --points 1000000 --ripple >/dev/null
fi
if [ ! -d "$W/lib" ]; then
  python3 - "$W/lib" <<'PY'
import importlib.util, os, sys, tempfile
spec = importlib.util.spec_from_file_location("cam", "fixtures/gen/cam_program.py")
cam = importlib.util.module_from_spec(spec); spec.loader.exec_module(cam)
root = sys.argv[1]
# One pocket-milling program cut to its first 1000 LIN points (the generator makes whole
# layers of 11250), then the retract; 1000 copies under 10 cell directories.
tmp = os.path.join(tempfile.mkdtemp(), "template.src")
cam.milling(tmp, 1000)
lines = open(tmp, newline="").read().split("\r\n")
head, n = [], 0
for l in lines:
    if l.startswith("LIN "):
        n += 1
        if n > 1000:
            break
    head.append(l)
tail = lines[lines.index("; retract, spindle off"):]
text = "\r\n".join(head + tail)
for i in range(1000):
    d = os.path.join(root, f"cell{i // 100:02d}")
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, f"prog{i:04d}.src"), "w", newline="") as f:
        f.write(text.replace("DEF template (", f"DEF prog{i:04d} ("))
PY
fi
measure() { # label, command...
  local label=$1; shift
  local log; log=$(mktemp)
  /usr/bin/time -v "$@" >/dev/null 2>"$log" || true
  local wall user sys rss
  wall=$(grep "Elapsed (wall clock)" "$log" | awk '{print $NF}')
  user=$(grep "User time" "$log" | awk '{print $NF}')
  sys=$(grep "System time" "$log" | awk '{print $NF}')
  rss=$(grep "Maximum resident" "$log" | awk '{print $NF}')
  printf '%-44s wall %8s  user %6s s  sys %6s s  peak %8.1f MB\n' "$label" "$wall" "$user" "$sys" "$(echo "$rss/1024" | bc -l)"
  rm -f "$log"
}
SIZE=$(stat -c %s "$W/cam1m.src")
LIBSIZE=$(du -sb "$W/lib" | awk '{print $1}')
echo "machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "1M-point program: $SIZE bytes ($(grep -c '^LIN' "$W/cam1m.src") LIN); library: 1000 programs, $LIBSIZE bytes"
rm -rf "$W/out" "$W/libout" "$W/cp.src" "$W/libcp"; mkdir -p "$W/out"
measure "cp (1M program)" cp "$W/cam1m.src" "$W/cp.src"
measure "robopost (1M program)" "$BIN" "$W/cam1m.src" -c "$CAL" -o "$W/out/cam1m.src"
measure "robopost --one-step (1M program)" "$BIN" "$W/cam1m.src" -c "$CAL" -o "$W/out/cam1m_one.src" --one-step
measure "robopost (1M rippled, identified cal)" "$BIN" "$W/cam1m_ripple.src" -c "$IDENTIFIED" -o "$W/out/cam1m_ripple.src"
measure "cp -r (1000 x 1000 library)" cp -r "$W/lib" "$W/libcp"
measure "robopost batch (1000 x 1000 library)" "$BIN" batch "$W/lib" -c "$CAL" -o "$W/libout"
