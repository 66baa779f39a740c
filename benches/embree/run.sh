#!/usr/bin/env bash
# Peer baseline: Intel Embree 3 (Debian's libembree-dev) on the standard meshes and ray sets of the trace benchmark
# (closest hit, then the shadow rays of each set: any hit). octaray's `bench-trace` traces the same work.
# usage: benches/embree/run.sh [OUTDIR]   (default /tmp/embree-peer); prints one line per configuration.
# THREADS=2 for two threads; ONLY_SHADOW=1 for the shadow (any-hit) lines only; SETUP_ONLY=1 to install, generate
# and build without running.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-/tmp/embree-peer}
mkdir -p "$out"
if ! [ -e /usr/include/embree3/rtcore.h ]; then
  apt-get update -qq >/dev/null && apt-get install -y -qq libembree-dev >/dev/null
fi
if ! [ -x "$out/venv/bin/python" ]; then
  python3 -m venv "$out/venv" && "$out/venv/bin/pip" install -q numpy
fi
[ -e "$out/data/torus1m.obj" ] || "$out/venv/bin/python" "$here/gen_data.py" "$out/data" >/dev/null
# rebuilt when the source is newer (another copy of the harness may have built here)
bin="$out/bench_e3_anyhit"
[ "$bin" -nt "$here/embree_bench.cpp" ] || g++ -O2 -march=native -std=c++17 -DE3 "$here/embree_bench.cpp" -o "$bin" -lembree3 -lpthread
[ -z "${SETUP_ONLY:-}" ] || exit 0
cd "$out"
for mesh in torus100k torus1m; do
  for rays in primary incoherent; do
    for q in "" shadow; do
      [ -z "${ONLY_SHADOW:-}" ] || [ -n "$q" ] || continue
      for mode in 1 8 16 1M; do "$bin" data/$mesh.mesh data/$rays.rays "${THREADS:-1}" $mode 5 $q; done
    done
  done
done
