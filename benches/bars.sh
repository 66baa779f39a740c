#!/usr/bin/env bash
# The speed bars in one run, peers and octaray back to back (ratios only mean
# something within one run on a shared machine). Usage, from the repository root:
#   benches/embree/run.sh /tmp/embree-peer          # once: builds bench_e3, makes the data
#   apt-get install povray hyperfine                 # once
#   benches/bars.sh [/tmp/embree-peer] [benches/povray]
set -euo pipefail
peer=${1:-/tmp/embree-peer}
pov=${2:-benches/povray}
cargo build --release -q
o=$PWD/target/release/octaray
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
uptime
(
  cd "$peer"
  ./bench_e3 data/torus100k.mesh data/primary.rays 1 8 5
  ./bench_e3 data/torus100k.mesh data/incoherent.rays 1 1 5
  ./bench_e3 data/torus1m.mesh data/primary.rays 1 8 3
)
"$o" bench-trace --rays "$peer/data" "$peer/data/torus100k.obj" 2>&1 | grep -v '^  ('
"$o" bench-trace --rays "$peer/data" "$peer/data/torus1m.obj" --reps 3 2>&1 | grep -E 'mode=8|bvh:'
uptime
# given scene 768², recursion level 4, whole process, 2 threads
# Each timed run writes a fresh file (--prepare): replacing an existing file by rename
# makes ext4 start writing the new one back first (auto_da_alloc), 20 ms of serial
# kernel time at 4K (strace -T on rename), which is the file system's cost, not ours.
fresh="sh -c 'rm -f $tmp/*.bmp $tmp/*.png'"
hyperfine -N -w 2 -r 15 --prepare "$fresh" --export-markdown "$tmp/given.md" \
  "$o render --size 768 -o $tmp/f.bmp" \
  "$o render --size 768 --profile reference -o $tmp/r.bmp"
cat "$tmp/given.md"
if command -v povray >/dev/null; then
  hyperfine -w 1 -r 5 --prepare "$fresh" --export-markdown "$tmp/pov.md" \
    "povray +I$pov/assignment_scene.pov +O$tmp/pov.png +FN +W768 +H768 -A +WT2 -D File_Gamma=1.0 Declare=RL=4" \
    "$o render $pov/assignment_scene.txt --size 768 --eye 100,100,50 --look-at 0,0,0 --threads 2 -o $tmp/o.bmp"
  cat "$tmp/pov.md"
  # the prism scene against POV-Ray's photon-mapped prism, 768², 2 threads each
  hyperfine -w 1 -r 3 --prepare "$fresh" --export-markdown "$tmp/prism.md" \
    "povray +I$pov/prism_dispersion.pov +O$tmp/povprism.png +FN +W768 +H768 -A +WT2 -D -GA File_Gamma=1.0" \
    "$o render scenes/prism_povray.txt --eye 10,-110,95 --look-at 30,0,8 --fov 60 --size 768 --threads 2 -o $tmp/op.png"
  cat "$tmp/prism.md"
fi
# 2 threads vs 1 on a 4K frame (render time reported by octaray itself, then whole process)
for t in 1 2 1 2; do "$o" render --size 3840x2160 --threads $t -o "$tmp/4k.bmp"; done
hyperfine -N -w 1 -r 5 --prepare "$fresh" \
  "$o render --size 3840x2160 --threads 1 -o $tmp/4k1.bmp" \
  "$o render --size 3840x2160 --threads 2 -o $tmp/4k2.bmp"
uptime
