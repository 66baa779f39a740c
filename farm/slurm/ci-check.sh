#!/usr/bin/env bash
# The farm scripts on a real cluster: starts a single-node Slurm cluster (Debian's
# slurmctld, slurmd and munge, as root, without systemd, configured in a scratch
# directory through SLURM_CONF), then
#   1. renders a 1920x1080 frame as an 8-task job array of tiles + an afterok assemble job,
#   2. renders a 4-frame camera path as a 4-task job array,
#   3. renders the frame as 4 tiles with GNU parallel (locally),
# checks each result against the one-process render byte for byte, and stops the
# daemons. Installs what it needs with apt-get where missing (root).
#
#   farm/slurm/ci-check.sh [OCTARAY]      (default: target/release/octaray, built if missing)
#
# Keeps its scratch directory on failure (set KEEP=1 to keep it anyway).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
bin=${1:-$root/target/release/octaray}
say() { printf 'ci-check: %s\n' "$*" >&2; }

if [ "$(id -u)" -ne 0 ]; then
  say "needs root (to start munged and slurmd)"; exit 1
fi
if [ ! -x "$bin" ]; then
  say "building $bin"
  (cd "$root" && cargo build --release)
fi
bin=$(realpath -- "$bin")

need=()
for tool in slurmctld:slurmctld slurmd:slurmd sbatch:slurm-client munged:munge parallel:parallel; do
  command -v "${tool%%:*}" >/dev/null || need+=("${tool#*:}")
done
if [ ${#need[@]} -gt 0 ]; then
  say "installing ${need[*]}"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi
[ -s /etc/munge/munge.key ] || { say "no /etc/munge/munge.key (munge's install makes it)"; exit 1; }

work=$(mktemp -d /tmp/octaray-slurm.XXXXXX)
chmod 755 "$work"
pids=()
stop() {
  local status=$?
  for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -9 "$pid" 2>/dev/null || true
  done
  if [ "$status" -ne 0 ] || [ -n "${KEEP:-}" ]; then
    say "kept $work (logs: $work/log)"
  else
    rm -rf "$work"
  fi
  exit "$status"
}
trap stop EXIT
trap 'exit 130' INT TERM

# munge: a daemon of its own on a socket of its own (another cluster may run here)
mkdir -p "$work/munge" "$work/log" "$work/state" "$work/spool"
chown munge:munge "$work/munge"
chmod 755 "$work/munge"   # (munged: the socket's directory must be searchable by all)
chown slurm:slurm "$work/state" "$work/log"
setpriv --reuid=munge --regid=munge --init-groups \
  munged --foreground --socket="$work/munge/socket" --pid-file="$work/munge/pid" \
  --log-file="$work/munge/log" --seed-file="$work/munge/seed" >"$work/log/munged.out" 2>&1 &
pids+=($!)

# two free TCP ports for slurmctld and slurmd
read -r ctld_port slurmd_port < <(python3 -c '
import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(*[x.getsockname()[1] for x in s])')
cpus=$(nproc)
export SLURM_CONF=$work/slurm.conf
cat > "$SLURM_CONF" <<CONF
ClusterName=octaray-ci
SlurmctldHost=localhost
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=slurm
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$work/munge/socket
MpiDefault=none
MailProg=/bin/true
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SchedulerParameters=sched_interval=1,bf_interval=1
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MinJobAge=600
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/log/slurmctld.pid
SlurmdPidFile=$work/spool/slurmd.pid
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/spool/slurmd.log
NodeName=localhost CPUs=$cpus RealMemory=1000
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF
for _ in $(seq 100); do [ -S "$work/munge/socket" ] && break; sleep 0.05; done
[ -S "$work/munge/socket" ] || { say "munged did not start"; exit 1; }
# (in the foreground, so that they are stopped by their PIDs; their log noise about
# PMIx and missing state files on a first start is harmless)
slurmctld -D -f "$SLURM_CONF" >"$work/log/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -f "$SLURM_CONF" -N localhost >"$work/log/slurmd.out" 2>&1 &
pids+=($!)
start=$(date +%s.%N)
until [ "$(sinfo -h -o %T 2>/dev/null)" = idle ] || [ $(($(date +%s) - ${start%.*})) -ge 60 ]; do
  sleep 0.1
done
[ "$(sinfo -h -o %T 2>/dev/null)" = idle ] || {
  say "the cluster did not come up"; tail -n 20 "$work"/log/*.out >&2; exit 1
}
say "cluster idle after $(python3 -c "print(f'{$(date +%s.%N) - $start:.1f}')") s ($cpus CPUs, ports $ctld_port, $slurmd_port)"

# Waits until the jobs have left the queue, then requires each to have COMPLETED.
wait_jobs() {
  local ids=$1 t0
  t0=$(date +%s)
  while [ -n "$(squeue -h -j "$ids" -o %i 2>/dev/null)" ]; do
    [ $(($(date +%s) - t0)) -lt 600 ] || { say "jobs $ids still queued after 600 s"; return 1; }
    sleep 0.2
  done
  local id states
  for id in ${ids//,/ }; do
    # (every task of an array; finished jobs stay known for MinJobAge)
    states=$(scontrol -o show job "$id" | grep -o 'JobState=[A-Z_]*' | sort | uniq -c)
    if [ -z "$states" ] || grep -qv 'JobState=COMPLETED' <<<"$states"; then
      say "job $id: not every task completed: ${states:-unknown}"
      tail -n 20 "$work"/*/slurm-*.out "$work"/*/*/slurm-*.out >&2 2>/dev/null || true
      return 1
    fi
  done
}

same() {
  if cmp -s "$1" "$2"; then say "equal byte for byte: $1 = $2"
  else say "DIFFERENT: $1 and $2"; return 1; fi
}

one=$work/one
mkdir -p "$one"

# 1. a 1920x1080 frame: 8 tiles, each on 2 cores (one at a time on a 2-core node), and assemble
frame=(--size 1920x1080)
"$bin" render "${frame[@]}" --threads 2 -o "$one/frame.png" 2>>"$work/log/renders.log"
t0=$(date +%s.%N)
read -r array assemble < <("$root/farm/slurm/render-frame.sh" -n 8 -c "$((cpus < 2 ? cpus : 2))" \
  -b "$bin" "$work/frame/frame.png" -- "${frame[@]}")
say "frame: tiles array $array, assemble job $assemble"
wait_jobs "$array,$assemble"
say "frame: 8 tiles + assemble in $(python3 -c "print(f'{$(date +%s.%N) - $t0:.1f}')") s"
same "$work/frame/frame.png" "$one/frame.png"
[ "$(ls "$work/frame/frame.png.tiles"/tile_*.png | wc -l)" -eq 8 ]

# 2. a 4-frame camera path through the prism's caustic: 4 tasks of one frame each
cat > "$work/path.txt" <<'PATH'
// eye                 look-at        up      fov
10 -110 95              30 0 8          0 0 1   60
0 -105 90               30 0 8          0 0 1   58
-10 -100 85             30 0 8          0 0 1   56
-20 -95 80              30 0 6          0 0 1   54
PATH
anim=("$root/scenes/prism.txt" --size 480x270)
t0=$(date +%s.%N)
array=$("$root/farm/slurm/render-animation.sh" -k 1 -c 1 -b "$bin" "$work/path.txt" 0 3 \
  "$work/frames/f_%04d.png" -- "${anim[@]}")
say "animation: array $array"
wait_jobs "$array"
say "animation: 4 frames in $(python3 -c "print(f'{$(date +%s.%N) - $t0:.1f}')") s"
k=0
while read -r ex ey ez lx ly lz ux uy uz fov; do
  case $ex in //*|"") continue ;; esac
  "$bin" render "${anim[@]}" --eye "$ex,$ey,$ez" --look-at "$lx,$ly,$lz" --up "$ux,$uy,$uz" \
    --fov "$fov" -o "$one/f_$k.png" 2>>"$work/log/renders.log"
  same "$work/frames/$(printf 'f_%04d.png' "$k")" "$one/f_$k.png"
  k=$((k + 1))
done < "$work/path.txt"
[ "$k" -eq 4 ]

# 3. GNU parallel on this machine: 4 tiles, 2 at a time, assembled
mkdir -p "$work/parallel"
seq 0 3 | parallel --will-cite -j2 --halt now,fail=1 \
  "$bin" render "${frame[@]}" --tile '{}/4' --threads 1 -o "$work/parallel/tile_{}.png" 2>>"$work/log/renders.log"
"$bin" assemble "$work"/parallel/tile_{0,1,2,3}.png -o "$work/parallel/frame.png" 2>>"$work/log/renders.log"
same "$work/parallel/frame.png" "$one/frame.png"

say "all results equal the one-process renders"
