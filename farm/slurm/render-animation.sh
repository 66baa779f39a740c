#!/usr/bin/env bash
# Submits the frames of a camera path to Slurm as a job array of chunks of frames
# (each task renders its chunk in turn on the cores it is given).
#
#   farm/slurm/render-animation.sh [-k CHUNK] [-c CPUS] [-b OCTARAY] [-m MAX] PATH.txt FIRST LAST PATTERN -- RENDER_ARGS...
#
#   PATH.txt     the camera path (one camera a line: eye, look-at, up, fov)
#   FIRST LAST   frames FIRST..LAST of it (from 0, inclusive)
#   PATTERN      the frames' names, printf-style: 'frames/f_%04d.png'
#   -k CHUNK     frames per task (default 1)
#   -c CPUS      --cpus-per-task; octaray uses $SLURM_CPUS_PER_TASK threads (default 2)
#   -b PATH      the octaray binary, as every node sees it (default: octaray on PATH)
#   -m MAX       at most MAX tasks at once (sbatch --array=...%MAX; default: no limit)
#   RENDER_ARGS  scene, --size, --profile, ...
#
# Prints the array job id. A requeued or resubmitted task skips the frames already
# written (--skip-existing). Other sbatch options come from the environment
# (SBATCH_PARTITION, SBATCH_TIMELIMIT, SBATCH_ACCOUNT, ...).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
chunk=1 cpus=2 bin=octaray max=""
while getopts "k:c:b:m:" opt; do
  case $opt in
    k) chunk=$OPTARG ;;
    c) cpus=$OPTARG ;;
    b) bin=$OPTARG ;;
    m) max=%$OPTARG ;;
    *) sed -n '2,20p' "$0" >&2; exit 2 ;;
  esac
done
shift $((OPTIND - 1))
[ $# -ge 4 ] || { sed -n '2,20p' "$0" >&2; exit 2; }
path=$(realpath -- "$1") first=$2 last=$3 pattern=$(realpath -m -- "$4")
shift 4
[ "${1:-}" = "--" ] && shift
case $bin in */*) bin=$(realpath -- "$bin") ;; esac
[ "$last" -ge "$first" ] && [ "$chunk" -ge 1 ] || { echo "render-animation.sh: need FIRST <= LAST and CHUNK >= 1" >&2; exit 2; }
tasks=$(( (last - first + chunk) / chunk ))
logs=$(dirname -- "$pattern")
mkdir -p -- "$logs"

array=$(sbatch --parsable --job-name=octaray-frames --array="0-$((tasks - 1))$max" \
  --cpus-per-task="$cpus" --output="$logs/slurm-%A_%a.out" \
  "$here/frames.sbatch" "$bin" "$path" "$first" "$last" "$chunk" "$pattern" "$@")
echo "${array%%;*}"
