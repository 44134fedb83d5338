#!/usr/bin/env bash
# fillgs bench resumed from what git keeps of a long run (its records, not its models), on a
# copy of the smoke comparison's folder (CTest: bench_paper_resume_*).
#   tests/bench_resume.sh FILLGS SMOKE_DIR OUT finished
#       every run finished, the models deleted: no backbone is trained or written, and
#       results.csv comes out byte for byte the same;
#   tests/bench_resume.sh FILLGS SMOKE_DIR OUT other-backbone
#       one run to make, the record's Gaussian count altered (what another machine's rounding
#       gives): the backbone trained again is refused with one line naming the record, and
#       not kept.
set -euo pipefail
fillgs=$1 smoke=$2 out=$3 mode=$4
rm -rf "$out"
cp -r "$smoke" "$out"
find "$out" -name model.ply -delete
fail() { echo "bench_resume ($mode): $*" >&2; exit 1; }
case $mode in
  finished)
    "$fillgs" bench --smoke --quiet --out "$out" >"$out.log"
    ! grep -q '^backbone' "$out.log" || fail "a backbone was trained: $(grep '^backbone' "$out.log" | head -1)"
    grep -q ': reused' "$out.log" || fail "no run reused"
    [ -z "$(find "$out" -name 'model*.ply')" ] || fail "a model was written: $(find "$out" -name 'model*.ply' | head -1)"
    cmp "$out/results.csv" "$smoke/results.csv" || fail "results.csv differs"
    ;;
  other-backbone)
    rm "$out"/*_s1/runs/no-refinement/result.json
    sed -i 's/"gaussians": [0-9]*/"gaussians": 1/' "$out"/*_s1/backbone/summary.json
    if "$fillgs" bench --smoke --quiet --out "$out" >/dev/null 2>"$out.err"; then fail "accepted"; fi
    [ "$(wc -l <"$out.err")" = 1 ] || fail "not one line: $(cat "$out.err")"
    grep -q 'backbone/summary.json: the backbone trained again is not the one this seed was made with (gaussians 1 there' "$out.err" ||
      fail "unexpected message: $(cat "$out.err")"
    [ -z "$(find "$out" -name 'model*.ply')" ] || fail "the other backbone was kept: $(find "$out" -name 'model*.ply' | head -1)"
    ;;
  *) fail "unknown mode" ;;
esac
