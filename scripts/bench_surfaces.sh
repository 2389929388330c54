#!/usr/bin/env bash
# The CAM surfaces a compensation must not slow down on (issue 35): 1M-point pocket-milling
# programs with the ripples CAM systems emit — a sawtooth zig-zag in Z (ripple 5–100 µm,
# period 3–15 points, on a 0.05 mm finishing pitch and on the 2 mm roughing pitch), a lateral
# sawtooth in Y, a 5-axis program with 0.01° orientation jitter, the scallop ripple of
# bench_compensate.sh — each compensated with the identified and the hand-set calibration.
# Every time is also given as a ratio to `robopost check` of the same file, measured in the
# same run just before it (machines differ, ratios travel). Usage:
#   scripts/bench_surfaces.sh [WORKDIR]      (default /tmp/robopost-surfaces; POINTS=N to scale)
# BEFORE=path/to/robopost also runs that binary right after each job (same file, same minute)
# and says whether its output file is the same bytes (`same`).
set -euo pipefail
cd "$(dirname "$0")/.."
W=${1:-/tmp/robopost-surfaces}
POINTS=${POINTS:-1000000}
BIN=${BIN:-target/dist/robopost}  # the packaged build (Cargo.toml: profile.dist)
[ -n "${NO_BUILD:-}" ] || cargo build --profile dist --quiet
mkdir -p "$W/out"
declare -A SURFACE=(
  [scallop]="--ripple"
  [sawtooth60x7]="--sawtooth 60,7 --spacing 0.05"
  [sawtooth100x3]="--sawtooth 100,3 --spacing 0.05"
  [sawtooth5x15]="--sawtooth 5,15 --spacing 0.05"
  [sawtooth60x7_rough]="--sawtooth 60,7"
  [lateral60x7]="--lateral 60,7 --spacing 0.05"
  [jitter5axis]="--jitter 0.01 --spacing 0.05"
)
run() { # prints "wall user peak_mb" of a command
  local log; log=$(mktemp)
  /usr/bin/time -f '%e %U %M' "$@" >/dev/null 2>"$log" || true
  tail -1 "$log" | awk '{printf "%s %s %.1f", $1, $2, $3/1024}'
  rm -f "$log"
}
echo "machine: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg), $POINTS points a program"
printf '%-20s %-10s %8s %8s %8s %9s %7s\n' surface calibration wall_s user_s peak_MB file_MB ratio
for name in $(printf '%s\n' "${!SURFACE[@]}" | sort); do
  src="$W/$name.src"
  # shellcheck disable=SC2086
  [ -f "$src" ] || python3 fixtures/gen/cam_program.py milling "$src" --points "$POINTS" ${SURFACE[$name]} >/dev/null
  mb=$(echo "$(stat -c %s "$src") / 1048576" | bc -l)
  read -r cw cu cm <<<"$(run "$BIN" check "$src")"
  printf '%-20s %-10s %8s %8s %8s %9.1f %7s\n' "$name" "(check)" "$cw" "$cu" "$cm" "$mb" "1.00"
  for cal in example handset; do
    read -r w u m <<<"$(run "$BIN" "$src" -c "calibrations/kr30ha-$cal.json" -o "$W/out/$name.src")"
    printf '%-20s %-10s %8s %8s %8s %9.1f %7.2f\n' "$name" "$cal" "$w" "$u" "$m" "$mb" "$(echo "$w / $cw" | bc -l)"
    if [ -n "${BEFORE:-}" ]; then
      read -r w u m <<<"$(run "$BEFORE" "$src" -c "calibrations/kr30ha-$cal.json" -o "$W/out/$name.before.src")"
      same=$(cmp -s "$W/out/$name.src" "$W/out/$name.before.src" && echo same || echo DIFFERS)
      printf '%-20s %-10s %8s %8s %8s %9.1f %7.2f %s\n' "$name" "$cal:before" "$w" "$u" "$m" "$mb" "$(echo "$w / $cw" | bc -l)" "$same"
    fi
  done
done
