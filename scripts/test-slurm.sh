#!/usr/bin/env bash
# Submits the job templates to a local single-node SLURM at a tiny size and
# checks what they write: kernels (JSON lines), the studies (on one node,
# or on two tasks started by srun --mpi=pmix), the partition sweep, and
# dem-run through signal -> checkpoint -> requeue -> resume, whose final
# checkpoint must equal an uninterrupted run's byte for byte.
# Usage: scripts/test-slurm.sh (as root; starts the local SLURM with
# scripts/slurm-local.sh and stops it again if it started it).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
scripts/install-deps.sh --slurm >/dev/null
cargo build --release -p experiments >&2
started=0
if ! sinfo -h >/dev/null 2>&1; then
  scripts/slurm-local.sh up
  started=1
fi
trap '[ "$started" -eq 1 ] && scripts/slurm-local.sh down' EXIT
work=out/test-slurm
rm -rf "$work"
mkdir -p "$work"
fail() { echo "test-slurm: FAIL: $*" >&2; exit 1; }
state_of() { scontrol show job "$1" -o 2>/dev/null | grep -o 'JobState=[A-Z_]*' | cut -d= -f2; }
# Waits for job $1 to end (at most $2 seconds) and prints its state.
finish() {
  local t=0 s
  while s=$(state_of "$1"); [[ "$s" =~ ^(PENDING|RUNNING|CONFIGURING|COMPLETING|REQUEUED)$ ]]; do
    sleep 1; t=$((t + 1)); [ "$t" -lt "$2" ] || fail "job $1 still $s after $2 s"
  done
  echo "$s"
}
# Plain sbatch, as users type it, from the repository root.
submit() { sbatch --parsable "$@"; }

id=$(submit jobs/kernels.sbatch 2000)
[ "$(finish "$id" 300)" = COMPLETED ] || fail "kernels: $(cat out/slurm-tridem-kernels-"$id".out)"
f=out/kernels-$id.jsonl
[ -s "$f" ] || fail "kernels wrote no $f"
if grep -qv '^{.*}$' "$f"; then fail "$f is not JSON lines"; fi
grep -q '"schedule":"dynamic"' "$f" || fail "$f has no dynamic rows"
echo "test-slurm: kernels ok ($(wc -l < "$f") rows)" >&2

id=$(submit jobs/study-accuracy.sbatch scenes/silo-1000.toml 20)
[ "$(finish "$id" 300)" = COMPLETED ] || fail "study-accuracy: $(cat out/slurm-tridem-accuracy-"$id".out)"
d=out/study-accuracy-$id
[ "$(wc -l < "$d/summary.csv")" -eq 14 ] || fail "$d/summary.csv"
[ -s "$d/accuracy.png" ] || fail "$d/accuracy.png"
echo "test-slurm: study-accuracy ok" >&2

id=$(submit --ntasks=2 jobs/study-exchange.sbatch scenes/silo-1000.toml 20)
[ "$(finish "$id" 300)" = COMPLETED ] || fail "study-exchange: $(cat out/slurm-tridem-exchange-"$id".out)"
d=out/study-exchange-$id
# A header, blocking and non-blocking, and blocking again for the noise floor.
[ "$(wc -l < "$d/summary.csv")" -eq 4 ] || fail "$d/summary.csv: $(cat "$d/summary.csv")"
grep -q '^blocking-2-again,noise floor,' "$d/summary.csv" || fail "$d/summary.csv has no noise floor"
echo "test-slurm: study-exchange ok (srun --mpi=pmix)" >&2

id=$(submit jobs/study-scheduling.sbatch scenes/silo-1000.toml 20)
[ "$(finish "$id" 300)" = COMPLETED ] || fail "study-scheduling: $(cat out/slurm-tridem-scheduling-"$id".out)"
[ -s "out/study-scheduling-$id/step-time.png" ] || fail "study-scheduling wrote no figures"
for study in partitioners repartition-frequency; do
  id=$(submit --ntasks=2 "jobs/study-$study.sbatch" scenes/silo-1000.toml 20)
  [ "$(finish "$id" 300)" = COMPLETED ] || fail "study-$study: $(cat out/slurm-tridem-"$study"-"$id".out)"
  [ -s "out/study-$study-$id/summary.csv" ] || fail "study-$study wrote no summary"
done
id=$(submit --ntasks=2 jobs/partition-sweep.sbatch 2000)
[ "$(finish "$id" 300)" = COMPLETED ] || fail "partition-sweep: $(cat out/slurm-tridem-partition-"$id".out)"
[ -n "$(ls out/partition-"$id")" ] || fail "partition-sweep wrote nothing"
echo "test-slurm: study-scheduling, study-partitioners, study-repartition-frequency, partition-sweep ok" >&2

# dem-run: the hopper uninterrupted, and as a job stopped by SLURM's signal
# once it has a checkpoint, requeued and resumed.
scene=scenes/hopper.toml
target/release/tridem run "$scene" --output "$work/straight" --threads 2 --quiet >/dev/null
id=$(submit --export=ALL,SCENE=$scene,DIR=$work/requeued jobs/dem-run.sbatch)
t=0
until [ -f "$work/requeued/checkpoint.h5" ]; do
  sleep 0.2; t=$((t + 1)); [ "$t" -lt 600 ] || fail "dem-run wrote no checkpoint"
done
scancel -b --signal=TERM "$id"
[ "$(finish "$id" 600)" = COMPLETED ] || fail "dem-run: $(cat out/slurm-tridem-dem-run-"$id".out)"
grep -q "stopped by a signal" out/slurm-tridem-dem-run-"$id".out || fail "dem-run was not stopped by the signal"
cmp "$work/straight/checkpoint.h5" "$work/requeued/checkpoint.h5" ||
  fail "the requeued run's final checkpoint differs from the uninterrupted run's"
# Submitted again, the finished run has nothing left to do: the job ends
# with success, saying so.
id=$(submit --export=ALL,SCENE=$scene,DIR=$work/requeued jobs/dem-run.sbatch)
[ "$(finish "$id" 120)" = COMPLETED ] || fail "dem-run submitted again: $(cat out/slurm-tridem-dem-run-"$id".out)"
grep -q "nothing left to run" out/slurm-tridem-dem-run-"$id".out || fail "dem-run submitted again did not say it had finished"
echo "test-slurm: dem-run ok (signal, checkpoint, requeue, resume: bit for bit; submitted again: nothing left)" >&2
echo "test-slurm: all templates ran" >&2
