#!/usr/bin/env bash
# The trace benchmark's fixed costs, set apart from the walks: the camera rays of the torus frames
# (benches/embree/frames.sh: 1920 x 1080, eye (0, -3.2, 2.2), 50 degrees, in 4 x 4 blocks, 16
# consecutive rays a block) traced by the Embree harness (modes 16 and 8) and by `octaray
# bench-trace` (the same modes) through the 4k-, 100k- and 1M-triangle tori and through one
# triangle that every ray misses. The miss-everything time is each side's floor: making the packets,
# the API's call, the root's test, reading the hits back. Each torus's time less that floor is
# what its tree costs. Prints the medians of ROUNDS interleaved rounds.
# usage, from the repository root:
#   benches/embree/walk_floor.sh [ROUNDS] [PEER_DIR]   (default 3 /tmp/embree-peer)
set -euo pipefail
rounds=${1:-3}
peer=${2:-/tmp/embree-peer}
here=$(cd "$(dirname "$0")" && pwd)
cargo build --release -q
o=$PWD/target/release/octaray
SETUP_ONLY=1 "$here/run.sh" "$peer"  # Embree, numpy, the tori, the harness
e=$peer/bench_e3_anyhit
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
PYTHONPATH=$here "$peer/venv/bin/python" - "$work" <<'PY'
import sys, numpy as np
import gen_data as g
g.out = sys.argv[1]
v, t = g.torus(50, 40); g.save_mesh('torus4k', v, t)
g.save_mesh('far1', np.array([[100, 100, 100], [101, 100, 100], [100, 101, 100]], np.float32),
            np.array([[0, 1, 2]], np.uint32))
g.save_rays('primary', *g.frame_rays())
PY
ln -s "$peer/data/incoherent.rays" "$work/incoherent.rays"
for m in torus100k torus1m; do ln -s "$peer/data/$m.mesh" "$work/$m.mesh"; ln -s "$peer/data/$m.obj" "$work/$m.obj"; done
log=$work/log
for ((r = 1; r <= rounds; r++)); do
  for m in far1 torus4k torus100k torus1m; do
    for mode in 16 8; do
      t=$("$e" "$work/$m.mesh" "$work/primary.rays" 1 $mode 5 | grep -o 'trace_ms=[0-9.]*')
      echo "$m embree $mode ${t#trace_ms=}" | tee -a "$log"
      t=$(OCTARAY_BENCH_ONLY=primary/$mode "$o" bench-trace --reps 5 --rays "$work" "$work/$m.obj" 2>/dev/null |
        grep -o 'trace_ms=[0-9.]*')
      echo "$m octaray $mode ${t#trace_ms=}" | tee -a "$log"
    done
  done
done
python3 - "$log" <<'PY'
import statistics as st, sys
t = {}
for line in open(sys.argv[1]):
    m, who, mode, ms = line.split()
    t.setdefault((m, who, mode), []).append(float(ms))
med = {k: st.median(v) for k, v in t.items()}
print(f'\ntrace ms of the 2 073 600 camera rays, median of {len(t[("far1", "embree", "16")])}; less the miss-everything floor')
for mode in ('16', '8'):
    for m in ('far1', 'torus4k', 'torus100k', 'torus1m'):
        e, o = med[(m, 'embree', mode)], med[(m, 'octaray', mode)]
        line = f'  mode={mode:2s} {m:9s} embree {e:6.1f}  octaray {o:6.1f}  ratio {o / e:.2f}'
        if m != 'far1':
            ew, ow = e - med[('far1', 'embree', mode)], o - med[('far1', 'octaray', mode)]
            line += f'   tree only: embree {ew:5.1f}  octaray {ow:5.1f}  ratio {ow / ew:.2f}'
        print(line)
PY
