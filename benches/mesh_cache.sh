#!/usr/bin/env bash
# The mesh cache: OBJ load time with the cache off, cold (parse the text, write the cache) and warm (read the
# cache), for torus100k and torus1m on 1 and 2 threads, in interleaved rounds; prints medians.
# Loader alone: bench-trace's load_ms (OCTARAY_BENCH_ONLY=none/none: load and build, no tracing). Whole process:
# `octaray render` of a scene holding the mesh at 8 x 8 (load, BVH build, render), wall seconds and peak RSS
# from /usr/bin/time. The cache lives in a temporary XDG_CACHE_HOME, removed at the end.
# usage: benches/mesh_cache.sh [ROUNDS] [PEER_DIR]   (default 5, /tmp/embree-peer: benches/embree/run.sh
# writes the meshes to PEER_DIR/data)
set -euo pipefail
rounds=${1:-5}
peer=${2:-/tmp/embree-peer}
root=$(cd "$(dirname "$0")/.." && pwd)
o=$root/target/release/octaray
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export XDG_CACHE_HOME=$work/cache
unset OCTARAY_MESH_CACHE
for mesh in torus100k torus1m; do
  printf '1 8 1 mesh %s  0.8 0.8 0.8  0.2 0.7 0.1 0  10  1 3 1 -2 1 1 1 0\n' "$peer/data/$mesh.obj" >"$work/$mesh.txt"
done
loader() { OCTARAY_BENCH_ONLY=none/none "$o" bench-trace "$peer/data/$1.obj" --threads "$2" 2>&1 >/dev/null |
  sed -n 's/.*load_ms=\([0-9.]*\).*/\1/p'; }
whole() { /usr/bin/time -f '%e %M' "$o" render "$work/$1.txt" --size 32 --threads "$2" --eye 0,2.2,2.6 \
  --look-at 0,0,0 --up 0,1,0 --fov 40 -o "$work/out.bmp" 2>&1 >/dev/null | tail -1; }
run() { # mesh threads state
  case $3 in
    off) export OCTARAY_MESH_CACHE=off ;;
    cold) unset OCTARAY_MESH_CACHE; rm -rf "$XDG_CACHE_HOME" ;;
    warm) unset OCTARAY_MESH_CACHE ;;
  esac
  echo "$1 $2 $3 loader_ms $(loader "$1" "$2")"
  [ "$3" != cold ] || rm -rf "$XDG_CACHE_HOME"
  set -- "$1" "$2" "$3" $(whole "$1" "$2")
  echo "$1 $2 $3 whole_s $4"
  echo "$1 $2 $3 peak_rss_MB $(awk -v k="$5" 'BEGIN { printf "%.1f", k / 1024 }')"
}
for ((r = 1; r <= rounds; r++)); do
  for threads in 1 2; do
    for mesh in torus100k torus1m; do
      for state in off cold warm; do run $mesh $threads $state; done
    done
  done
done >"$work/all.txt"
echo "mesh threads measure: off / cold / warm, medians of $rounds rounds (warm / off)"
for mesh in torus100k torus1m; do
  for threads in 1 2; do
    for measure in loader_ms whole_s peak_rss_MB; do
      m() { awk -v a="$mesh" -v t="$threads" -v s="$1" -v k="$measure" '$1 == a && $2 == t && $3 == s && $4 == k { print $5 }' \
        "$work/all.txt" | sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
      off=$(m off) cold=$(m cold) warm=$(m warm)
      echo "$mesh $threads $measure: $off / $cold / $warm ($(awk -v w="$warm" -v f="$off" 'BEGIN { printf "%.2f", w / f }')x)"
    done
  done
done
for mesh in torus100k torus1m; do
  rm -rf "$XDG_CACHE_HOME"
  loader $mesh 1 >/dev/null
  echo "$mesh cache file: $(cat "$XDG_CACHE_HOME"/octaray/mesh/*.mesh | wc -c) bytes"
done
