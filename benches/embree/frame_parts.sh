#!/usr/bin/env bash
# Where the whole-frame gap to the Embree tracer lies, ray kind by ray kind: the frames of
# frames.sh rendered three ways by both programs, render part only (each program's own
# summary line), interleaved rounds:
#   camera   no lights, recursion level 1: camera rays and their shading (ambient)
#   +shadow  the point light, recursion level 1: camera rays and their shadow rays
#   whole    the light and recursion level 4 (the frames.sh frame): adds the mirror rays
# The difference of two rows is the cost of what the second adds. Prints medians per program
# and the per-round ratio octaray / Embree of each row and of each difference.
# usage, from the repository root:
#   benches/embree/frame_parts.sh [ROUNDS] [PEER_DIR] [TORUS_DIR]   (default 5 /tmp/embree-peer /tmp/torus)
# Run benches/embree/frames.sh once first: it builds the Embree tracer and writes the torus scenes.
set -euo pipefail
rounds=${1:-5}
peer=${2:-/tmp/embree-peer}
tdir=${3:-/tmp/torus}
cargo build --release -q
o=$PWD/target/release/octaray
e=$peer/whitted
[ -x "$e" ] && [ -e "$tdir/torus1m.txt" ] || { echo "run benches/embree/frames.sh first" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cam=(--eye 0,-3.2,2.2 --look-at 0,0,0 --fov 50 --size 1920x1080 --threads 1)
# the scene of frames.sh (recursion level 4, one point light), then with level 1, then also
# without the light
obj='mesh\n%s\n0.8 0.6 0.3\n0.2 0.5 0.3 0.3\n20\n'
for mesh in torus100k torus1m; do
  printf "4\n1080\n1\n${obj}1\n3 -4 6\n1 1 1\n0\n" "$peer/data/$mesh.obj" >"$work/$mesh.whole.txt"
  printf "1\n1080\n1\n${obj}1\n3 -4 6\n1 1 1\n0\n" "$peer/data/$mesh.obj" >"$work/$mesh.shadow.txt"
  printf "1\n1080\n1\n${obj}0\n0\n" "$peer/data/$mesh.obj" >"$work/$mesh.camera.txt"
  cmp -s "$work/$mesh.whole.txt" "$tdir/$mesh.txt" || { echo "$tdir/$mesh.txt is not frames.sh's scene" >&2; exit 1; }
  "$o" render "$work/$mesh.camera.txt" "${cam[@]}" -o "$work/x.bmp" 2>&1 | grep -q '(2073600 primary, 0 shadow, 0 reflection)' ||
    { echo "the camera scene traces more than camera rays" >&2; exit 1; }
done
log=$work/log
for ((r = 1; r <= rounds; r++)); do
  for mesh in torus100k torus1m; do
    for part in camera shadow whole; do
      for who in octaray embree; do
        if [ $who = octaray ]; then cmd=("$o" render); else cmd=("$e"); fi
        s=$("${cmd[@]}" "$work/$mesh.$part.txt" "${cam[@]}" -o "$work/$who.bmp" 2>&1 | grep -o 'render [0-9.]* s' | head -1)
        echo "$mesh $part $who ${s#render }" | tee -a "$log"
      done
    done
  done
done
python3 - "$log" <<'PY'
import statistics as st, sys
t = {}
for line in open(sys.argv[1]):
    mesh, part, who, s, _ = line.split()
    t.setdefault((mesh, part, who), []).append(float(s))
for mesh in ('torus100k', 'torus1m'):
    print(f'\n{mesh}: render part, s, median of {len(t[(mesh, "whole", "octaray")])}; ratio octaray / embree per round, median [min-max]')
    rows = [('camera', 'camera', None), ('+shadow', 'shadow', None), ('whole', 'whole', None),
            ('shadow rays (+shadow - camera)', 'shadow', 'camera'), ('mirror rays (whole - +shadow)', 'whole', 'shadow')]
    for name, part, minus in rows:
        v = {}
        for who in ('octaray', 'embree'):
            a = t[(mesh, part, who)]
            v[who] = [x - y for x, y in zip(a, t[(mesh, minus, who)])] if minus else a
        r = sorted(a / b for a, b in zip(v['octaray'], v['embree']))
        print(f'  {name:32s} octaray {st.median(v["octaray"]):.3f}  embree {st.median(v["embree"]):.3f}'
              f'  ratio {st.median(r):.2f} [{r[0]:.2f}-{r[-1]:.2f}]')
PY
