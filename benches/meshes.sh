#!/usr/bin/env bash
# The mesh figures against Embree in interleaved rounds: per round and mesh, the Embree harness
# (benches/embree, modes 1/8/16 and the stream 1M, closest hit and shadow rays) then octaray
# bench-trace (modes 1/8/16/64, the binary 1b/8b and the stream 1s) on the
# same work, 1 thread; prints every line, then the median Mrays/s of each cell over the rounds,
# octaray's best mode over Embree's best mode, and the median and range over the rounds of
# each round's best over best. Usage, from the repository root:
#   benches/meshes.sh [ROUNDS] [/tmp/embree-peer]
set -euo pipefail
rounds=${1:-3}
peer=${2:-/tmp/embree-peer}
here=$(cd "$(dirname "$0")" && pwd)
cargo build --release -q
o=$PWD/target/release/octaray
SETUP_ONLY=1 "$here/embree/run.sh" "$peer"  # installs, generates, builds
e=$peer/bench_e3_anyhit
log=$(mktemp)
uptime
for i in $(seq "$rounds"); do
  for mesh in torus100k torus1m; do
    for rays in primary incoherent; do
      for q in "" shadow; do
        for mode in 1 8 16 1M; do
          (cd "$peer" && "$e" "data/$mesh.mesh" "data/$rays.rays" 1 $mode 5 $q) | tee -a "$log"
        done
      done
    done
    "$o" bench-trace --rays "$peer/data" "$peer/data/$mesh.obj" 2>/dev/null | tee -a "$log"
  done
done
uptime
python3 - "$log" <<'PY'
import re, statistics, sys
cells = {}
for line in open(sys.argv[1]):
    f = dict(re.findall(r'(\S+)=(\S+)', line))
    mesh = re.sub(r'.*/|\.(mesh|obj)$', '', f['mesh'])
    rays = re.sub(r'.*/|\.rays', '', f['rays'])
    who = 'embree' if line.startswith('embree') else 'octaray'
    cells.setdefault((mesh, rays), {}).setdefault((who, f['mode']), []).append(
        (float(f['Mrays/s']), f['hits'], f['mean_t']))
for (mesh, rays), modes in cells.items():
    med = {k: statistics.median(x[0] for x in v) for k, v in modes.items()}
    best = lambda who: max((v, k[1]) for k, v in med.items() if k[0] == who)
    (eb, em), (ob, om) = best('embree'), best('octaray')
    row = ' '.join(f'{w}{m}={v:.2f}' for (w, m), v in sorted(med.items()))
    hits = {w: modes[(w, m)][0][1:] for w, m in [('embree', em), ('octaray', om)]}
    # each round's own best over best (both sides' modes run back to back in a round)
    rounds = min(len(v) for v in modes.values())
    per = sorted(max(v[r][0] for k, v in modes.items() if k[0] == 'octaray')
                 / max(v[r][0] for k, v in modes.items() if k[0] == 'embree') for r in range(rounds))
    print(f'{mesh} {rays}: {row} | best octaray mode={om} {ob:.2f} / embree mode={em} {eb:.2f} = {ob / eb:.2f}x'
          f' | per round {statistics.median(per):.2f}x ({per[0]:.2f}-{per[-1]:.2f})'
          f' | hits, mean_t: embree {hits["embree"]}, octaray {hits["octaray"]}')
PY
rm -f "$log"
