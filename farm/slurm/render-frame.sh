#!/usr/bin/env bash
# Submits one frame to Slurm as a job array of tiles (one task per tile, each on the
# cores it is given) and an assemble job that runs once every tile has succeeded.
#
#   farm/slurm/render-frame.sh [-n TILES] [-c CPUS] [-t TILE_DIR] [-b OCTARAY] [-m MAX] OUT.png -- RENDER_ARGS...
#
#   -n TILES   tiles = array tasks (default 8)
#   -c CPUS    --cpus-per-task; octaray renders each tile on $SLURM_CPUS_PER_TASK threads (default 2)
#   -t DIR     where the tiles go, on storage every node sees (default OUT.tiles/)
#   -b PATH    the octaray binary, as every node sees it (default: octaray on PATH)
#   -m MAX     at most MAX tasks at once (sbatch --array=...%MAX; default: no limit)
#   RENDER_ARGS  what `octaray render` takes for the whole frame: scene, --size, camera, --profile
#
# Prints the two job ids ("ARRAY ASSEMBLE"). Other sbatch options come from the
# environment (SBATCH_PARTITION, SBATCH_TIMELIMIT, SBATCH_ACCOUNT, ...). A requeued or
# resubmitted array skips the tiles already written (--skip-existing).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
tiles=8 cpus=2 dir="" bin=octaray max=""
while getopts "n:c:t:b:m:" opt; do
  case $opt in
    n) tiles=$OPTARG ;;
    c) cpus=$OPTARG ;;
    t) dir=$OPTARG ;;
    b) bin=$OPTARG ;;
    m) max=%$OPTARG ;;
    *) sed -n '2,18p' "$0" >&2; exit 2 ;;
  esac
done
shift $((OPTIND - 1))
[ $# -ge 1 ] || { sed -n '2,18p' "$0" >&2; exit 2; }
out=$(realpath -m -- "$1"); shift
[ "${1:-}" = "--" ] && shift
dir=$(realpath -m -- "${dir:-$out.tiles}")
case $bin in */*) bin=$(realpath -- "$bin") ;; esac
mkdir -p -- "$dir"

array=$(sbatch --parsable --job-name=octaray-tiles --array="0-$((tiles - 1))$max" \
  --cpus-per-task="$cpus" --output="$dir/slurm-%A_%a.out" \
  "$here/tile.sbatch" "$bin" "$tiles" "$dir" "$@")
array=${array%%;*}
assemble=$(sbatch --parsable --job-name=octaray-assemble --dependency="afterok:$array" \
  --kill-on-invalid-dep=yes --cpus-per-task=1 --output="$dir/slurm-%j-assemble.out" \
  "$here/assemble.sbatch" "$bin" "$tiles" "$dir" "$out")
echo "${array} ${assemble%%;*}"
