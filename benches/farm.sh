#!/usr/bin/env bash
# The figures a farm user plans with (benches/README.md, "Farm: per-tile overhead and
# frames per hour"), whole-process times:
#   1. per-tile overhead at 4K, 4x4 supersampled: a process that renders one pixel
#      (start, scene parse, BVH build, photon map, digest, PNG) against the tiles of the
#      frame in 4, 16 and 64 tiles, for the given scene and the prism scene;
#   2. frames per hour of a 4K flythrough (a camera path of FRAMES frames).
#
#   benches/farm.sh [OCTARAY] [THREADS] [FRAMES]   (default: target/release/octaray, 2, 4)
#
# Needs hyperfine and /usr/bin/time (Debian: hyperfine, time). Prints markdown tables.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bin=$(realpath -- "${1:-$root/target/release/octaray}")
threads=${2:-2}
frames=${3:-4}
work=$(mktemp -d /tmp/octaray-farm-bench.XXXXXX)
trap 'rm -rf "$work"' EXIT
printf 'samples_per_pixel = 16\n' > "$work/ss16.toml"
size=${SIZE:-3840x2160}   # (SIZE=96x64 for a dry run)
secs() { /usr/bin/time -f %e "$@" 2>&1 >/dev/null | tail -n 1; }
mean() { python3 -c "import sys; v=[float(x) for x in sys.argv[1:]]; print(f'{sum(v)/len(v):.3f}')" "$@"; }

echo "load before: $(cut -d' ' -f1-3 /proc/loadavg); $(nproc) CPUs; octaray --threads $threads"
echo
echo "| scene | one-pixel process (overhead) | whole frame | tiles | mean tile | slowest tile | sum of tiles | overhead / mean tile |"
echo "|---|---|---|---|---|---|---|---|"
for scene in given prism; do
  args=("$root/scenes/$scene.txt" --size "$size" --profile "$work/ss16.toml" --threads "$threads")
  hyperfine -N -w 2 -r 20 --export-json "$work/o.json" \
    "$bin render ${args[*]} --crop 0,1,0,1 -o $work/o.png" >/dev/null 2>&1
  o=$(python3 -c "import json; r=json.load(open('$work/o.json'))['results'][0]; print(f\"{r['mean']:.4f} {r['stddev']:.4f}\")")
  whole=$(secs "$bin" render "${args[@]}" -o "$work/whole.png")
  for n in 4 16 64; do
    times=()
    for ((i = 0; i < n; i++)); do
      times+=("$(secs "$bin" render "${args[@]}" --tile "$i/$n" -o "$work/t_$i.png")")
    done
    "$bin" assemble "$work"/t_*.png -o "$work/a.png" 2>/dev/null
    cmp -s "$work/a.png" "$work/whole.png" || { echo "assembled $n tiles differ from the whole frame" >&2; exit 1; }
    rm -f "$work"/t_*.png
    python3 - "$scene" "$o" "$whole" "$n" "${times[@]}" <<'PY'
import sys
scene, o, whole, n, *t = sys.argv[1:]
om, osd = map(float, o.split())
t = [float(x) for x in t]
mean = sum(t) / len(t)
print(f"| {scene} | {om*1e3:.1f} ± {osd*1e3:.1f} ms | {float(whole):.2f} s | {n} | {mean:.3f} s "
      f"| {max(t):.3f} s ({max(t)/mean:.2f}x mean) | {sum(t):.2f} s | **{100*om/mean:.2f} %** |")
PY
  done
done

echo
echo "load between: $(cut -d' ' -f1-3 /proc/loadavg)"
echo
# a flythrough: FRAMES cameras circling the scene at the viewer's benchmark radius
python3 - "$frames" > "$work/flight.txt" <<'PY'
import math, sys
n = int(sys.argv[1])
for k in range(n):
    a = math.radians(45 + 3 * k)
    print(f"{141.42*math.cos(a):.4f} {141.42*math.sin(a):.4f} {50 + 20*math.sin(2*a):.4f}  0 0 10  0 0 1  80")
PY
echo "| scene, 4K 4x4 supersampled | frames | whole process | per frame | prepare per frame | frames per hour |"
echo "|---|---|---|---|---|---|"
for scene in given prism; do
  log=$work/frames-$scene.log
  mkdir -p "$work/frames-$scene"
  /usr/bin/time -f %e "$bin" render "$root/scenes/$scene.txt" --size "$size" \
    --profile "$work/ss16.toml" --threads "$threads" --camera-path "$work/flight.txt" \
    -o "$work/frames-$scene/f_%04d.png" 2>"$log"
  t=$(tail -n 1 "$log")
  prep=$(grep -o 'prepare [0-9.]* s' "$log" | awk '{s+=$2} END {printf "%.3f", s/NR}')
  python3 -c "
t, n, p = $t, $frames, $prep
print(f'| $scene | {n} | {t:.2f} s | {t/n:.2f} s | {p:.3f} s | **{3600*n/t:.0f}** |')"
done
echo
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
