#!/usr/bin/env bash
# Interleaved rounds of the three torus100k bars that sit near their line (ratios within
# one round; report the median over rounds). Usage, from the repository root:
#   benches/rounds.sh [ROUNDS] [/tmp/embree-peer]
# Each line: Embree primary mode=8, octaray primary/8 and primary/1, the packet/single
# ratio, octaray/Embree on primary; Embree incoherent mode=1, octaray incoherent/1, ratio.
set -euo pipefail
rounds=${1:-8}
peer=${2:-/tmp/embree-peer}
cargo build --release -q
o=$PWD/target/release/octaray
mesh=$peer/data/torus100k.obj
rate() { grep -o 'Mrays/s=[0-9.]*' | cut -d= -f2; }
oct() { OCTARAY_BENCH_ONLY=$1 "$o" bench-trace "$mesh" 2>&1 | rate; }
emb() { (cd "$peer" && ./bench_e3 data/torus100k.mesh "data/$1.rays" 1 "$2" 5) | rate; }
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", a / b }'; }
uptime
for i in $(seq "$rounds"); do
  e8=$(emb primary 8); o8=$(oct primary/8); o1=$(oct primary/1)
  e1=$(emb incoherent 1); oi=$(oct incoherent/1)
  echo "round $i: embree8 $e8 oct8 $o8 oct1 $o1 packet/single $(ratio "$o8" "$o1")" \
    "vs-embree $(ratio "$o8" "$e8") | incoherent: embree1 $e1 oct1 $oi ratio $(ratio "$oi" "$e1")"
done
uptime
