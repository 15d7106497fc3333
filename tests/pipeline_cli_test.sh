#!/bin/sh
# bisturi pipeline and bisturi cohort from the command line, without a cluster: a cohort of
# vessel phantoms, each case through its array task's script body (SLURM_ARRAY_TASK_ID set by
# hand), gathered and checked against the phantoms' truth; idempotence (an unchanged case does no
# work, a changed plan redoes it); failures (a truncated scan, a bad plan) leave a result.json
# that names the error and exit non-zero; the gather lists the failed task with the exact rerun
# command; nothing is written outside the case's folder; the session solid runs in a session scene.
# usage: pipeline_cli_test.sh BISTURI WORKDIR SOURCE_DIR
set -eu
bisturi=$1 work=$2 src=$3
rm -rf "$work" && mkdir -p "$work/cwd"
cd "$work/cwd"  # stays empty: nothing may be written outside --out
fail() { echo "FAIL: $*"; exit 1; }

"$bisturi" cohort phantoms --out "$work/ph" --count 4 > /dev/null
plan=$work/ph/plan.toml
scan=$work/ph/scans/case-00.nrrd

# One case; result.json has the issue's fields.
"$bisturi" pipeline "$scan" --plan "$plan" --out "$work/one" --json > "$work/one.json"
grep -q '"status": "ok"' "$work/one/result.json" || fail "case not ok"
for key in distance_mm centre_mm normal mean_diameter_mm area_mm2 perimeter_mm branch sha256 \
           timings_ms version; do
  grep -q "\"$key\"" "$work/one/result.json" || fail "result.json lacks $key"
done
for f in result.json surface.ply vessel.obj scene_solid.toml centreline.csv profile.png; do
  [ -s "$work/one/$f" ] || fail "no $f"
done
[ -z "$(ls "$work/one" | grep partial || true)" ] || fail "partial files left"
[ -z "$(ls -A "$work/cwd")" ] || fail "files written outside --out: $(ls -A "$work/cwd")"

# The session solid goes into a session scene as written: the default scene with its vessel
# replaced by scene_solid.toml's entry (the mesh named from the scene's folder), run briefly.
mkdir -p "$work/session"
"$bisturi" run --print-default-scene |
  awk '/^\[\[solids\]\]/ { held = $0; next } held != "" { if ($0 ~ /^name = "vessel"/) skip = 1; else print held; held = "" }
       /^\[\[devices\]\]/ { skip = 0 } !skip { print }' > "$work/session/scene.toml"
sed "s|^mesh = \"vessel.obj\"|mesh = \"$work/one/vessel.obj\"|" "$work/one/scene_solid.toml" >> "$work/session/scene.toml"
"$bisturi" run "$work/session/scene.toml" --duration 0.1 --eye-width 32 --eye-height 32 --no-openxr \
  --cpu --out "$work/session/out" --json > "$work/session/report.json" 2> "$work/session/err.txt" ||
  fail "the session did not take the solid: $(tail -3 "$work/session/err.txt")"
grep -q '"name": "case-00"' "$work/session/report.json" || fail "the session has no case-00 solid"

# Unchanged: no work, result untouched. Changed plan: redone.
before=$(cksum < "$work/one/result.json")
"$bisturi" pipeline "$scan" --plan "$plan" --out "$work/one" | grep -q "up to date" || fail "not idempotent"
[ "$before" = "$(cksum < "$work/one/result.json")" ] || fail "result.json rewritten"
sed 's/section_step_mm = 2.0/section_step_mm = 3.0/' "$plan" > "$work/plan3.toml"
"$bisturi" pipeline "$scan" --plan "$work/plan3.toml" --out "$work/one" | grep -q "up to date" &&
  fail "a changed plan was taken as up to date"
grep -q '"distance_mm": 9.0' "$work/one/result.json" || fail "the new step is not used"

# A truncated scan: exit 1, result.json names the stage and the file, no meshes.
head -c 3000 "$scan" > "$work/truncated.nrrd"
if "$bisturi" pipeline "$work/truncated.nrrd" --plan "$plan" --out "$work/bad" 2> "$work/bad.err"; then
  fail "a truncated scan succeeded"
fi
grep -q '"status": "failed"' "$work/bad/result.json" || fail "no failed status"
grep -q '"stage": "read"' "$work/bad/result.json" || fail "no failed stage"
grep -q 'truncated.nrrd' "$work/bad/result.json" || fail "the error does not name the file"
[ ! -e "$work/bad/vessel.obj" ] || fail "a failed case wrote a mesh"
# A plan with a typo: the file, line and key are named.
printf '[segmentation]\nmethod = "threshold"\nrnage = [1, 2]\n' > "$work/typo.toml"
if "$bisturi" pipeline "$scan" --plan "$work/typo.toml" --out "$work/typo" 2> "$work/typo.err"; then
  fail "a bad plan succeeded"
fi
grep -q "typo.toml: line 3: key 'segmentation.rnage': unknown key" "$work/typo.err" ||
  fail "bad plan message: $(cat "$work/typo.err")"

# A seed on the vessel's axis (the truth's first piece, halfway) picks it; one in the background
# fails and says why.
seed=$(awk -F, '$1 == "case-00" && $2 == 0 { printf "%f, %f, %f", ($3 + $6) / 2, ($4 + $7) / 2, ($5 + $8) / 2 }' "$work/ph/truth.csv")
sed "s/^range = .*/&\nseed_mm = [$seed]/" "$plan" > "$work/seed.toml"
"$bisturi" pipeline "$scan" --plan "$work/seed.toml" --out "$work/seed" > /dev/null || fail "seeded case"
grep -q '"segmented_by": "seed"' "$work/seed/result.json" || fail "not segmented by the seed"
sed "s/^range = .*/&\nseed_mm = [-20.0, 0.0, 0.0]/" "$plan" > "$work/seed_out.toml"
"$bisturi" pipeline "$scan" --plan "$work/seed_out.toml" --out "$work/seed_out" 2> /dev/null &&
  fail "a seed outside the vessel succeeded"
grep -q 'seed_mm (-20.000000, 0.000000, 0.000000) is outside the volume' "$work/seed_out/result.json" ||
  fail "seed message: $(grep message "$work/seed_out/result.json")"

# Label maps (`bisturi segment`'s output): method = "label"; a binary surface is a staircase,
# so diameters are good to about a quarter voxel (0.25 mm here) instead of hundredths.
printf 'case,scan,shape\n' > "$work/labels.csv"
for c in 00 01 02 03; do
  "$bisturi" segment "$work/ph/scans/case-$c.nrrd" --threshold 150 2000 --out "$work/labels-$c.nrrd" > /dev/null
  printf 'case-%s,labels-%s.nrrd,%s\n' $c $c "$(awk -F, -v c="case-$c" '$1 == c { print $3 }' "$work/ph/manifest.csv")" >> "$work/labels.csv"
done
printf '[segmentation]\nmethod = "label"\nlabel = 1\n[cluster]\nmax_running = 2\n' > "$work/label_plan.toml"
"$bisturi" cohort plan "$work/labels.csv" --plan "$work/label_plan.toml" --out "$work/label_cohort" > /dev/null
for task in 0 1 2 3; do
  SLURM_ARRAY_TASK_ID=$task bash "$work/label_cohort/cohort.sbatch" > /dev/null 2>&1 || fail "label task $task"
done
"$bisturi" cohort gather "$work/label_cohort" > /dev/null || fail "label gather"
sh "$src/slurm/check_against_truth.sh" "$work/labels.csv" "$work/ph/truth.csv" \
  "$work/label_cohort/cohort.csv" "$work/label_cohort/cohort_cases.csv" 0.25 0.4

# A sloppy manifest (a BOM, CRLF, a comment, a blank line, quotes, columns in another order)
# is read; a case listed twice is refused with its line.
printf '\357\273\277"scan" , case,notes\r\n# a comment\r\n\r\n"scans/case-00.nrrd",a,"x, y"\r\nscans/case-01.nrrd, b ,\r\n' > "$work/ph/sloppy.csv"
"$bisturi" cohort plan "$work/ph/sloppy.csv" --plan "$plan" --out "$work/sloppy" > /dev/null || fail "sloppy manifest"
[ "$(tail -n +2 "$work/sloppy/cases.tsv" | cut -f3 | tr '\n' ' ')" = "a b " ] || fail "sloppy cases: $(cat "$work/sloppy/cases.tsv")"
printf 'case,scan\na,scans/case-00.nrrd\na,scans/case-01.nrrd\n' > "$work/ph/twice.csv"
"$bisturi" cohort plan "$work/ph/twice.csv" --plan "$plan" --out "$work/twice" 2> "$work/twice.err" &&
  fail "a case listed twice was accepted"
grep -q "twice.csv: line 3: case 'a' is listed twice" "$work/twice.err" || fail "$(cat "$work/twice.err")"

# The cohort: plan, run each array task's body, gather, check against the truth.
cohort=$work/cohort
"$bisturi" cohort plan "$work/ph/manifest.csv" --plan "$plan" --out "$cohort" > /dev/null
grep -q '^#SBATCH --array=0-3%3$' "$cohort/cohort.sbatch" || fail "array line"
grep -q '^#SBATCH --mem=500M$' "$cohort/cohort.sbatch" || fail "mem line"
grep -q "^#SBATCH --output=$cohort/logs/task-%a.job-%A.log\$" "$cohort/cohort.sbatch" || fail "log line"
for task in 0 1 2 3; do
  SLURM_ARRAY_TASK_ID=$task bash "$cohort/cohort.sbatch" > "$cohort/logs/task-$task.local.log" 2>&1 ||
    fail "task $task: $(cat "$cohort/logs/task-$task.local.log")"
done
"$bisturi" cohort gather "$cohort" > "$work/gather.txt" || fail "gather: $(cat "$work/gather.txt")"
sh "$src/slurm/check_against_truth.sh" "$work/ph/manifest.csv" "$work/ph/truth.csv" \
  "$cohort/cohort.csv" "$cohort/cohort_cases.csv"

# A case that fails is listed with the command that reruns exactly its task.
cp "$work/ph/scans/case-02.nrrd" "$work/case-02.good"
head -c 2000 "$work/case-02.good" > "$work/ph/scans/case-02.nrrd"
SLURM_ARRAY_TASK_ID=2 bash "$cohort/cohort.sbatch" > /dev/null 2>&1 && fail "task 2 succeeded"
status=0
"$bisturi" cohort gather "$cohort" > "$work/gather2.txt" || status=$?
[ "$status" = 3 ] || fail "gather exit $status with a failed case"
grep -q "not ok: case 2 (case-02, task 2): read: " "$work/gather2.txt" || fail "$(cat "$work/gather2.txt")"
grep -q "rerun them: sbatch --array=2%3 $cohort/cohort.sbatch" "$work/gather2.txt" ||
  fail "rerun line: $(cat "$work/gather2.txt")"
cp "$work/case-02.good" "$work/ph/scans/case-02.nrrd"
SLURM_ARRAY_TASK_ID=2 bash "$cohort/cohort.sbatch" > /dev/null 2>&1 || fail "task 2 rerun"
"$bisturi" cohort gather "$cohort" --json > "$work/gather3.json" || fail "gather after the rerun"
grep -q '"rerun": null' "$work/gather3.json" || fail "still a rerun after the fix"
# A case made with another plan is stale, and listed for a rerun.
cp "$cohort/plan.toml" "$work/plan.saved"
sed -i 's/section_step_mm = 2.0/section_step_mm = 2.5/' "$cohort/plan.toml"
"$bisturi" cohort gather "$cohort" > "$work/gather4.txt" && fail "stale results taken as ok"
grep -q "rerun them: sbatch --array=0-3%3 $cohort/cohort.sbatch" "$work/gather4.txt" ||
  fail "stale: $(cat "$work/gather4.txt")"
cp "$work/plan.saved" "$cohort/plan.toml"
[ -z "$(ls -A "$work/cwd")" ] || fail "files written outside the cohort: $(ls -A "$work/cwd")"
echo "pipeline and cohort: ok"
