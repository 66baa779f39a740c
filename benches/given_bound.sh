#!/usr/bin/env bash
# How far the given-scene bar (768², recursion level 4, whole process, >= 20x the
# reference) is from reach: the given scene with its work taken away piece by piece,
# whole process, 2 threads, beside the full scene and the reference, in one hyperfine
# run. If even the camera rays alone (no lights, no mirrors) take longer than the
# reference's time / 20, no shading or shadow speed-up can meet the bar.
# Usage, from the repository root: benches/given_bound.sh [RUNS=20]
set -euo pipefail
runs=${1:-20}
cargo build --release -q
o=$PWD/target/release/octaray
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
g=scenes/given.txt
# the given scene's lines: 1 recursion level, 2 pixels, 3-63 objects, 64-72 point lights,
# 74-78 the spotlight (checked below, so that an edit of the file cannot skew this)
[ "$(sed -n 64p $g)" = 4 ] && [ "$(sed -n 74p $g)" = 1 ] || { echo "scenes/given.txt changed"; exit 1; }
{ echo 1; sed -n 2,63p $g; echo 0; echo 0; } > "$tmp/camera_rays_only.txt"
{ echo 4; sed -n 2,63p $g; echo 0; echo 0; } > "$tmp/no_lights.txt"
{ echo 1; sed -n 2,79p $g; } > "$tmp/no_mirrors.txt"
fresh="sh -c 'rm -f $tmp/*.bmp'"
uptime
hyperfine -N -w 3 -r "$runs" --prepare "$fresh" \
  "$o render $tmp/camera_rays_only.txt --size 768 -o $tmp/a.bmp" \
  "$o render $tmp/no_lights.txt --size 768 -o $tmp/b.bmp" \
  "$o render $tmp/no_mirrors.txt --size 768 -o $tmp/c.bmp" \
  "$o render $g --size 768 -o $tmp/d.bmp" \
  "$o render $g --size 768 --profile reference -o $tmp/e.bmp" \
  "$o render $g --size 8 -o $tmp/f.bmp"
uptime
