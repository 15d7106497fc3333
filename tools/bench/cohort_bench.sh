#!/bin/sh
# Cases per hour of `bisturi pipeline` on this machine, per stage, on CT-sized vessel phantoms
# (512 x 512 x 256 samples of 0.7 mm, float, 20 HU noise: the field of view of an abdominal CT
# around one vessel), through `bisturi cohort` run locally (each array task's body by hand).
# The peers, measured right after each case on its file: coreutils' sha256sum (the checksum
# stage's bound) and `bisturi volume info` (a bare read). The machine's load drifts: read the
# ratios, not the absolute times.
# usage: tools/bench/cohort_bench.sh BISTURI [CASES (4)] [WORKDIR (/tmp/bisturi_cohort_bench)]
set -eu
bisturi=$1 cases=${2:-4} work=${3:-/tmp/bisturi_cohort_bench}
rm -rf "$work" && mkdir -p "$work"
echo "cohort_bench: writing $cases CT-sized phantoms (about 250 MB each) ..."
"$bisturi" cohort phantoms --out "$work/ph" --count "$cases" --spacing 0.7 --fov 358 358 179 \
  --noise 20 > /dev/null
"$bisturi" cohort plan "$work/ph/manifest.csv" --plan "$work/ph/plan.toml" --out "$work/cohort" > /dev/null
now() { date +%s.%N; }
peer_sha=0 peer_read=0
i=0
while [ "$i" -lt "$cases" ]; do
  SLURM_ARRAY_TASK_ID=$i bash "$work/cohort/cohort.sbatch" > /dev/null
  # The peers right after the case, on the same file (the machine's load drifts).
  f=$(printf '%s/ph/scans/case-%02d.nrrd' "$work" "$i")
  t0=$(now); sha256sum "$f" > /dev/null; t1=$(now)
  "$bisturi" volume info "$f" > /dev/null; t2=$(now)
  peer_sha=$(echo "$peer_sha $t0 $t1" | awk '{ print $1 + $3 - $2 }')
  peer_read=$(echo "$peer_read $t1 $t2" | awk '{ print $1 + $3 - $2 }')
  i=$((i + 1))
done
"$bisturi" cohort gather "$work/cohort" > /dev/null
awk -F, -v n="$cases" -v sha="$peer_sha" -v rd="$peer_read" '
  NR == 1 { for (k = 13; k <= 21; k++) name[k] = $k; next }
  $4 == "ok" { ok++; for (k = 13; k <= 21; k++) { v[k, ok] = $k } }
  END {
    printf "cohort_bench: %d of %d cases ok; median per case (ms) and cases per hour on one core\n", ok, n
    for (k = 13; k <= 21; k++) {
      m = 0; for (i = 1; i <= ok; i++) a[i] = v[k, i]
      for (i = 1; i <= ok; i++) for (j = i + 1; j <= ok; j++) if (a[j] < a[i]) { t = a[i]; a[i] = a[j]; a[j] = t }
      m = ok % 2 ? a[(ok + 1) / 2] : (a[ok / 2] + a[ok / 2 + 1]) / 2
      sum[k] = 0; for (i = 1; i <= ok; i++) sum[k] += a[i]
      sub(/_ms$/, "", name[k])
      printf "  %-11s %9.1f ms %10.0f cases/h\n", name[k], m, (m > 0 ? 3600000 / m : 0)
    }
    printf "peer (same files): sha256sum %.2f s for all, the checksum stage %.2f s (ratio %.2f); volume info %.2f s, the read stage %.2f s (ratio %.2f)\n", sha, sum[14] / 1000, sum[14] / 1000 / sha, rd, sum[15] / 1000, sum[15] / 1000 / rd
  }' "$work/cohort/cohort_cases.csv"
