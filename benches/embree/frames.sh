#!/usr/bin/env bash
# Whole frames against a Whitted tracer on Embree 3 (benches/embree/whitted.cpp, the same scene, camera and shading):
# the 100k- and 1M-triangle tori, 1920 x 1080, recursion level 4, 1 thread, whole process. Per round and torus:
# octaray with its mesh cache warm, octaray with OCTARAY_MESH_CACHE=off, the Embree tracer, and the Embree tracer
# with --floor-last (the floor tested after Embree's traversal, as octaray orders it, instead of bounding the ray)
# (order rotated each round); wall time (bash's EPOCHREALTIME around /usr/bin/time) and peak RSS (/usr/bin/time). Prints every run,
# then medians, spreads, the ratios octaray / embree (of the medians and of each round's pair), both programs'
# time split and ray counts, and how far the images differ.
# usage, from the repository root:
#   benches/embree/frames.sh [ROUNDS] [PEER_DIR] [TORUS_DIR]   (default 5 /tmp/embree-peer /tmp/torus)
# PEER_DIR holds the meshes (SETUP_ONLY=1 benches/embree/run.sh PEER_DIR writes them, and is run here); the scenes
# TORUS_DIR/torus100k.txt and torus1m.txt are written if missing.
set -euo pipefail
rounds=${1:-5}
peer=${2:-/tmp/embree-peer}
tdir=${3:-/tmp/torus}
here=$(cd "$(dirname "$0")" && pwd)
cargo build --release -q
o=$PWD/target/release/octaray
SETUP_ONLY=1 "$here/run.sh" "$peer"  # Embree, numpy, the meshes
e=$peer/whitted
[ "$e" -nt "$here/whitted.cpp" ] ||
  g++ -O3 -march=native -fno-math-errno -std=c++17 "$here/whitted.cpp" -o "$e" -lembree3 -lpthread
py=$peer/venv/bin/python
mkdir -p "$tdir"
for mesh in torus100k torus1m; do
  [ -e "$tdir/$mesh.txt" ] || printf '4\n1080\n1\nmesh\n%s\n0.8 0.6 0.3\n0.2 0.5 0.3 0.3\n20\n1\n3 -4 6\n1 1 1\n0\n' \
    "$peer/data/$mesh.obj" >"$tdir/$mesh.txt"
done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export XDG_CACHE_HOME=$work/cache  # octaray's mesh cache, private to this run
unset OCTARAY_MESH_CACHE
cam=(--eye 0,-3.2,2.2 --look-at 0,0,0 --fov 50 --size 1920x1080 --threads 1)

# one timed run: prints "MESH WHO wall_s rss_kB | the program's summary line"
run() { # mesh who
  local out=$work/$1.$2.bmp cmd
  case $2 in
    embree) cmd=("$e" "$tdir/$1.txt" "${cam[@]}" -o "$out") ;;
    embree_fl) cmd=("$e" "$tdir/$1.txt" "${cam[@]}" --floor-last -o "$out") ;;
    warm) cmd=("$o" render "$tdir/$1.txt" "${cam[@]}" -o "$out") ;;
    off) cmd=(env OCTARAY_MESH_CACHE=off "$o" render "$tdir/$1.txt" "${cam[@]}" -o "$out") ;;
  esac
  # a fresh output file each run: replacing one by rename costs ext4 a write-back of the new file first
  rm -f "$out"
  local t0=$EPOCHREALTIME
  /usr/bin/time -f 'rss_kB %M' -o "$work/time" "${cmd[@]}" 2>"$work/err" >/dev/null
  local t1=$EPOCHREALTIME
  printf '%s %s %s %s | %s\n' "$1" "$2" "$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.4f", b - a }')" \
    "$(sed -n 's/^rss_kB //p' "$work/time")" \
    "$(grep -E ' rays \(' "$work/err" | tail -1)"
}

for mesh in torus100k torus1m; do run $mesh warm >/dev/null; done  # writes the mesh cache
log=$work/log
uptime
order=(warm embree off embree_fl)
for ((r = 1; r <= rounds; r++)); do
  for mesh in torus100k torus1m; do
    for who in "${order[@]}"; do run $mesh $who | tee -a "$log"; done
  done
  order=("${order[@]:1}" "${order[0]}")
done
uptime
"$py" - "$log" "$work" <<'PY'
import re, statistics as st, sys
import numpy as np
log, work = sys.argv[1], sys.argv[2]
runs = {}
for line in open(log):
    head, summary = line.split(' | ', 1)
    mesh, who, wall, rss = head.split()
    runs.setdefault((mesh, who), []).append((float(wall), int(rss), summary.strip()))

def split(summary):
    """(name, seconds) pairs of a summary line's parenthesised times, and its ray counts."""
    times = re.findall(r'(load|build|prepare|render|write) ([0-9.]+) s', summary)
    rays = re.search(r'\((\d+) primary, (\d+) shadow, (\d+) reflection\)', summary)
    return times, tuple(int(x) for x in rays.groups()) if rays else None

def bmp(path):
    b = open(path, 'rb').read()
    off, w, h = (int.from_bytes(b[i:i + 4], 'little', signed=True) for i in (10, 18, 22))
    row = (w * 3 + 3) & ~3
    a = np.frombuffer(b, np.uint8, row * abs(h), off).reshape(abs(h), row)[:, :w * 3].reshape(abs(h), w, 3)
    return (a[::-1] if h > 0 else a).astype(int)

for mesh in ('torus100k', 'torus1m'):
    e, efl = runs[(mesh, 'embree')], runs[(mesh, 'embree_fl')]
    print(f'\n{mesh}: wall s, median [min-max] of {len(e)}; peak RSS MB, median; program\'s own split, medians')
    for who in ('warm', 'off', 'embree', 'embree_fl'):
        rs = runs[(mesh, who)]
        walls = [x[0] for x in rs]
        parts = {}
        for wall, _, s in rs:
            times = split(s)[0]
            for name, v in times:
                parts.setdefault(name, []).append(float(v))
            # what the program's own split leaves out of the whole process: for octaray the scene and mesh load,
            # for both start-up and exit
            parts.setdefault('rest', []).append(wall - sum(float(v) for _, v in times))
        part = ', '.join(f'{n} {st.median(v):.3f}' for n, v in parts.items())
        name = {'warm': 'octaray (cache warm)', 'off': 'octaray (cache off)', 'embree': 'embree whitted',
                'embree_fl': 'embree --floor-last'}[who]
        line = (f'  {name:22s} {st.median(walls):.3f} [{min(walls):.3f}-{max(walls):.3f}]'
                f'  rss {st.median(x[1] for x in rs) / 1024:.1f} MB  ({part})')
        for base, label in ((e, 'embree'), (efl, 'embree --floor-last')):
            if who in ('embree', 'embree_fl'):
                break
            pair = [a[0] / b[0] for a, b in zip(rs, base)]
            line += (f'\n  {"":22s} octaray / {label}: of medians {st.median(walls) / st.median(x[0] for x in base):.3f},'
                     f' per round median {st.median(pair):.3f} [{min(pair):.3f}-{max(pair):.3f}]')
        print(line)
    ro, re_ = split(runs[(mesh, 'warm')][0][2])[1], split(e[0][2])[1]
    print('  rays (primary, shadow, reflection): octaray', ro, 'embree', re_,
          'embree/octaray - 1 in ppm', tuple(round((b / a - 1) * 1e6, 1) for a, b in zip(ro, re_)))
    a, b = bmp(f'{work}/{mesh}.warm.bmp'), bmp(f'{work}/{mesh}.embree.bmp')
    d = np.abs(a - b).max(axis=2)
    print(f'  image: {d.size} pixels, {np.sum(d == 0)} identical, {np.sum(d > 2)} differ by more than 2/255'
          f' ({100 * np.mean(d > 2):.3f} %), max difference {d.max()}/255')
PY
