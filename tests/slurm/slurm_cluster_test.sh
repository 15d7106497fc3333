#!/bin/bash
# A real Slurm cluster on this machine, from Debian's packages (slurm-wlm, munge): one munged
# with its own key and socket, one slurmctld and three slurmd (n1-n3, one CPU each, Debian's
# build allows several on one host), all in a private folder, no systemd, no accounting. Submits
# `bisturi cohort plan`'s job array over generated vessel phantoms (one with a truncated scan),
# waits for it, gathers, checks the table against the phantoms' truth and the failed case's
# rerun command, runs that command, gathers again, and stops every daemon it started, by pid.
# Needs root (the daemons switch users and own their spool); exits 77 (skipped) otherwise.
# usage: slurm_cluster_test.sh BISTURI WORKDIR SOURCE_DIR
set -euo pipefail
bisturi=$1 work=$2 src=$3
if [ "$(id -u)" -ne 0 ]; then
  echo "SKIP: the Slurm test starts slurmctld, slurmd and munged and needs root"
  exit 77
fi
for tool in munged slurmctld slurmd sbatch squeue scontrol sinfo; do
  command -v "$tool" > /dev/null || { echo "FAIL: $tool not found (tools/install-deps.sh installs slurm-wlm and munge)"; exit 1; }
done
rm -rf "$work" && mkdir -p "$work"
work=$(cd "$work" && pwd)
pids=()
stop_all() {
  for p in "${pids[@]}"; do kill "$p" 2> /dev/null || true; done
  for p in "${pids[@]}"; do
    for _ in $(seq 50); do kill -0 "$p" 2> /dev/null || break; sleep 0.1; done
    kill -9 "$p" 2> /dev/null || true
  done
}
trap stop_all EXIT
fail() {
  echo "FAIL: $*"
  for f in "$work"/slurmctld.log "$work"/slurmd-n1.log; do [ -f "$f" ] && { echo "--- $f"; tail -20 "$f"; }; done
  exit 1
}
wait_until() {  # SECONDS COMMAND...: poll every 0.2 s
  local limit=$1; shift
  local end=$((SECONDS + limit))
  until "$@"; do [ $SECONDS -lt $end ] || return 1; sleep 0.2; done
}

# --- munge: a private key, socket and files (the folder 0755: munged refuses 0700 parents) ---
mkdir -p "$work/munge" && chmod 0755 "$work/munge"
dd if=/dev/urandom of="$work/munge/munge.key" bs=1024 count=1 status=none
chmod 0400 "$work/munge/munge.key"
munged -F --force --socket="$work/munge/munge.socket" --key-file="$work/munge/munge.key" \
  --pid-file="$work/munge/munged.pid" --log-file="$work/munge/munged.log" \
  --seed-file="$work/munge/munged.seed" > "$work/munge/stdout.log" 2>&1 &
pids+=($!)
wait_until 10 test -S "$work/munge/munge.socket" || fail "munged did not start: $(cat "$work/munge/munged.log")"

# --- Slurm: ports from the pid so that two runs on one machine do not meet ---
base=$((20000 + ($$ % 2000) * 4))
mkdir -p "$work/state" "$work/spool"
cat > "$work/slurm.conf" << CONF
ClusterName=bisturi-test
SlurmctldHost=localhost
SlurmctldPort=$base
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$work/munge/munge.socket
CredType=cred/munge
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool/%n
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd-%n.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd-%n.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SlurmdParameters=config_overrides
SchedulerType=sched/backfill
SchedulerParameters=batch_sched_delay=0,sched_min_interval=0,sched_interval=1,bf_interval=1
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
MinJobAge=600
KillWait=5
NodeName=n[1-3] NodeHostname=localhost NodeAddr=127.0.0.1 Port=$((base + 1))-$((base + 3)) CPUs=1 RealMemory=4000 State=UNKNOWN
PartitionName=test Nodes=n[1-3] Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$work/slurm.conf
t_start=$SECONDS
slurmctld -D -i > "$work/slurmctld.stdout" 2>&1 &
pids+=($!)
for n in 1 2 3; do
  mkdir -p "$work/spool/n$n"
  slurmd -D -N "n$n" > "$work/slurmd-n$n.stdout" 2>&1 &
  pids+=($!)
done
idle3() { [ "$(sinfo -h -N -o '%T' 2> /dev/null | grep -c '^idle')" = 3 ]; }
wait_until 60 idle3 || fail "the nodes did not come up: $(sinfo -N 2>&1)"
echo "slurm: 3 nodes idle after $((SECONDS - t_start)) s"

# --- the cohort: six phantoms, case 4's scan truncated ---
"$bisturi" cohort phantoms --out "$work/ph" --count 6 > /dev/null
cp "$work/ph/scans/case-04.nrrd" "$work/case-04.good"
head -c 2000 "$work/case-04.good" > "$work/ph/scans/case-04.nrrd"
cohort=$work/cohort
"$bisturi" cohort plan "$work/ph/manifest.csv" --plan "$work/ph/plan.toml" --out "$cohort" > /dev/null

job_done() { [ -z "$(squeue -h -j "$1" 2> /dev/null)" ]; }
t0=$(date +%s.%N)
job=$(sbatch --parsable "$cohort/cohort.sbatch") || fail "sbatch"
job=${job%%;*}
wait_until 180 job_done "$job" || fail "job $job did not finish: $(squeue -j "$job" 2>&1)"
t1=$(date +%s.%N)
scontrol show job "$job" > "$work/job.txt"
grep -q "ExitCode=1:0" "$work/job.txt" || fail "no task exited 1: $(grep -E 'ArrayTaskId|ExitCode' "$work/job.txt")"
[ "$(ls "$cohort"/logs/task-*.job-"$job".log | wc -l)" = 6 ] || fail "not 6 task logs"
nodes=$(grep -ho 'on n[1-3]' "$cohort"/logs/task-*.job-"$job".log | sort -u | wc -l)

status=0
"$bisturi" cohort gather "$cohort" > "$work/gather1.txt" || status=$?
cat "$work/gather1.txt"
[ "$status" = 3 ] || fail "gather exit $status, expected 3 (one case failed)"
rerun=$(sed -n 's/^rerun them: //p' "$work/gather1.txt")
[ "$rerun" = "sbatch --array=4%3 $cohort/cohort.sbatch" ] || fail "rerun command: '$rerun'"

# --- the fix and the rerun of exactly that task ---
cp "$work/case-04.good" "$work/ph/scans/case-04.nrrd"
submitted=$($rerun) || fail "rerun: $submitted"  # exactly as printed
job2=${submitted##* }
wait_until 120 job_done "$job2" || fail "rerun job $job2 did not finish"
[ "$(ls "$cohort"/logs/task-*.job-"$job2".log | wc -l)" = 1 ] || fail "the rerun ran more than one task"
"$bisturi" cohort gather "$cohort" > "$work/gather2.txt" || fail "gather after the rerun: $(cat "$work/gather2.txt")"
cat "$work/gather2.txt"
sh "$src/slurm/check_against_truth.sh" "$work/ph/manifest.csv" "$work/ph/truth.csv" \
  "$cohort/cohort.csv" "$cohort/cohort_cases.csv"

# --- the cost of Slurm per task: the array's wall time against the work its tasks did ---
work_s=$(awk -F, 'NR > 1 && $4 == "ok" { s += $13 } END { printf "%.3f", s / 1000 }' "$cohort/cohort_cases.csv")
awk -v t0="$t0" -v t1="$t1" -v w="$work_s" 'BEGIN {
  wall = t1 - t0
  printf "slurm: 6 array tasks on 3 one-CPU nodes in %.2f s (submit to last task done); pipeline work %.2f s in all; overhead about %.2f s per task ((3 x wall - work) / 6)\n", wall, w, (3 * wall - w) / 6 }'
# Slurm's own cost: an array of six tasks that do nothing, submit to done.
t2=$(date +%s.%N)
empty=$(sbatch --parsable --array=0-5 --output=/dev/null --wrap=true) || fail "sbatch --wrap"
wait_until 60 job_done "${empty%%;*}" || fail "the empty array did not finish"
t3=$(date +%s.%N)
awk -v t0="$t2" -v t1="$t3" 'BEGIN { printf "slurm: 6 empty array tasks on 3 nodes in %.2f s: %.2f s of node time per task\n", t1 - t0, 3 * (t1 - t0) / 6 }'
echo "slurm: tasks ran on $nodes node(s)"
[ "$nodes" -ge 2 ] || fail "the array ran on one node only"
echo "slurm cohort: ok"
