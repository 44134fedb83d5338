#!/usr/bin/env bash
# bench/pool_select.sh resumed from the records git keeps (its .gitignore): on a finished smoke
# folder, every model removed and two strategies' steps deleted, the script trains the seed's
# backbone again, checks it against model.sha256 and reruns the steps (--jobs 2: both
# strategies at once, a core each) to the same choices and the same metrics; a backbone that comes out otherwise (a changed model.sha256) stops it.
# The smoke folder was made with FILLGS_INSTRUCTION_SET=sse4 (CTest), and this resumes it without:
# the script must read SSE4 from the records and hold fillgs to it; held to the CPU's widest
# instead, the backbone trained again is another model and is refused.
#   tests/pool_select_resume.sh OUT FILLGS SCRIPT   (OUT: a finished `pool_select.sh --smoke OUT`)
set -euo pipefail
out=$1 fillgs=$2 script=$3
unset FILLGS_INSTRUCTION_SET
test -f "$out/results.md"
grep -q '^cpu .*, sse4 (a CPU with .*, held to sse4 by FILLGS_INSTRUCTION_SET)$' "$out/s1/backbone/step.txt"
row=(choose.random.K2/pool_chosen.json scratch.random.K2/eval_near/metrics.json scratch.random.K2/eval_far/metrics.json
  choose.negative.K2/pool_chosen.json scratch.negative.K2/eval_near/metrics.json scratch.negative.K2/eval_far/metrics.json)
rm -rf "$out/before" && mkdir -p "$out/before"
cp "$out/s1/backbone/model.sha256" "$out/before/model.sha256"
for f in "${row[@]}"; do cp "$out/s1/$f" "$out/before/${f//\//_}"; done
forget() {  # what a fresh checkout lacks: every model, and two strategies' steps
  find "$out/s1" -name '*.ply' -delete
  rm -rf "$out/s1/choose.random.K2" "$out/s1/scratch.random.K2" "$out/s1/choose.negative.K2" "$out/s1/scratch.negative.K2"
}
forget
# Resumed two jobs at a time, each on a core of its own: the same choices and metrics.
FILLGS=$fillgs bash "$script" --smoke --jobs 2 "$out" >/dev/null 2>"$out/resume.err"
grep -q "s1/backbone/step.txt ran on sse4 and this CPU has .*: every step runs with FILLGS_INSTRUCTION_SET=sse4" "$out/resume.err"
grep -q "s1/backbone/model.ply is not here (git keeps the records, not the models): training it again" "$out/resume.err"
test -s "$out/s1/scratch.random.K2/model.ply"
for f in "${row[@]}"; do cmp "$out/s1/$f" "$out/before/${f//\//_}"; done
# A run of some strategies only (here random, FillGS's runs absent) finishes, its picture
# without a FillGS tile, instead of asking for a FillGS run that was never requested.
rm -rf "$out/aside" && mkdir -p "$out/aside"
for d in choose.fillgs.K2 scratch.fillgs.K2; do mv "$out/s1/$d" "$out/aside/"; done
FILLGS=$fillgs bash "$script" --strategies random --smoke "$out" >"$out/random.out" 2>"$out/resume.err"
grep -q "^picture: ground truth | scratch.control | .*scratch.random.K2 at held-out camera" "$out/random.out"
! grep -q "^picture: .*fillgs" "$out/random.out"
for d in "$out"/aside/*; do mv "$d" "$out/s1/"; done
# Held to the CPU's widest instead of the recorded SSE4, the backbone is another model.
forget
if FILLGS_INSTRUCTION_SET=native FILLGS=$fillgs bash "$script" --smoke "$out" >/dev/null 2>"$out/resume.err"; then
  echo "pool_select_resume: a backbone trained on another instruction set than its records was accepted" >&2
  exit 1
fi
grep -q "s1/backbone trained again is not the model its finished rows used (model.sha256)" "$out/resume.err"
# A record cut to its first line vouches for init_points.ply alone: it is refused, and a
# backbone trained on another instruction set (another model.ply, the same initial points)
# does not get through it.
forget
head -n 1 "$out/before/model.sha256" >"$out/s1/backbone/model.sha256"
if FILLGS_INSTRUCTION_SET=native FILLGS=$fillgs bash "$script" --smoke "$out" >/dev/null 2>"$out/resume.err"; then
  echo "pool_select_resume: a model.sha256 that does not cover model.ply was trusted" >&2
  exit 1
fi
grep -q "s1/backbone/model.sha256 names init_points.ply, not exactly the backbone's init_points.ply model.ply" "$out/resume.err"
cp "$out/before/model.sha256" "$out/s1/backbone/model.sha256"
# A backbone that does not come out as the one the finished rows used is refused.
forget
awk 'NR == 1 { $0 = (substr($0, 1, 1) == "0" ? "1" : "0") substr($0, 2) } { print }' "$out/s1/backbone/model.sha256" >"$out/sha.tmp"
mv "$out/sha.tmp" "$out/s1/backbone/model.sha256"
if FILLGS=$fillgs bash "$script" --smoke "$out" >/dev/null 2>"$out/resume.err"; then
  echo "pool_select_resume: a backbone unlike its model.sha256 was accepted" >&2
  exit 1
fi
grep -q "s1/backbone trained again is not the model its finished rows used (model.sha256)" "$out/resume.err"
test ! -e "$out/s1/scratch.random.K2"
echo "pool_select_resume: resumed from SSE4 records to the same choice and metrics; a backbone of another instruction set or hash, and a record covering less than the backbone, refused"
