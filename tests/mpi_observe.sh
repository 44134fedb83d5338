#!/usr/bin/env bash
# fillgs observe --mpi under mpirun gives the single process's .npy tables byte for byte
# (2 and 3 ranks; 3 does not divide the 5 frames), and a bad input ends every rank with
# one error line from fillgs and exit 1. Usage: mpi_observe.sh FILLGS WORKDIR
set -euo pipefail
fillgs=$1
work=$2
rm -rf "$work"
mkdir -p "$work"
cd "$work"
# Root is allowed to run MPI jobs in CI and containers; shared-memory single copy is off
# where the container forbids ptrace between processes.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
"$fillgs" synth --out scene --frames 5 --width 48 --height 36 --quiet >/dev/null
common=(--scene scene/scene.ply --cameras scene/transforms_extrapolation.json --quiet --no-plots --threads 1)
status=0
for mode in "raytraced --stride 2" "frustum --motion-tables dynamic"; do
  # shellcheck disable=SC2086
  "$fillgs" observe "${common[@]}" --mode $mode --out one >/dev/null
  for np in 2 3; do
    # shellcheck disable=SC2086
    mpirun -np $np --oversubscribe "$fillgs" observe "${common[@]}" --mode $mode --out "np$np" --mpi >/dev/null
    for f in one/*.npy; do
      if cmp -s "$f" "np$np/$(basename "$f")"; then echo "same: $mode, $np ranks, $(basename "$f")"
      else echo "DIFFERENT: $mode, $np ranks, $(basename "$f")"; status=1; fi
    done
    [ "$(ls one/*.npy | wc -l)" -ge 5 ] || { echo "too few tables in one/"; status=1; }
    rm -rf "np$np"
  done
  rm -rf one
done
set +e
errors=$(mpirun -np 2 --oversubscribe "$fillgs" observe --scene missing.ply --cameras scene/transforms_extrapolation.json --out bad --mpi 2>&1 >/dev/null)
code=$?
set -e
lines=$(printf '%s\n' "$errors" | grep -c '^error:' || true)
if [ "$code" -ne 0 ] && [ "$lines" -eq 1 ] && printf '%s' "$errors" | grep -q 'missing.ply' && [ ! -e bad ]; then
  echo "bad input: exit $code, one error line, nothing written"
else
  echo "bad input: exit $code, $lines error lines, bad/ exists: $([ -e bad ] && echo yes || echo no)"; printf '%s\n' "$errors"; status=1
fi
[ "$status" -eq 0 ] && echo "mpi_observe: all tables byte-identical"
exit "$status"
