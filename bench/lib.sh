# Shared by the resumable benchmark scripts (bench/panoptic_rig.sh, bench/pool_select.sh).
#
# step DIR DONE COMMAND...: runs COMMAND (whose output folder is DIR) unless DIR/DONE exists
# and DIR/command.txt holds the same command line; a finished step made by another command
# line is refused. The model a step reads is part of its identity through the step that
# made it. Prints how long a step that ran took (seconds) to stderr and writes it, with the
# time it finished (UTC), the commit of the checkout that ran it and the CPU (cpu_line), to
# DIR/step.txt.
#
# finished DIR DONE COMMAND...: whether step would reuse DIR (without running anything).
finished() {
  local dir=$1 done=$2
  shift 2
  [ -f "$dir/$done" ] && [ "$(cat "$dir/command.txt" 2>/dev/null)" = "$(printf '%s\n' "$@")" ]
}
# The machine a step ran on, as far as its numbers depend on it: the CPU's name, core count
# and widest vector extension (the SIMD target fillgs's kernels dispatch to, so AVX2 and
# AVX-512 machines round differently and train different models from the same command).
cpu_line() {
  local name simd=sse4
  name=$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo 2>/dev/null | head -1)
  grep -qw avx2 /proc/cpuinfo 2>/dev/null && simd=avx2
  grep -qw avx512f /proc/cpuinfo 2>/dev/null && simd=avx512
  echo "${name:-unknown}, $(nproc) cores, $simd"
}
step() {
  local dir=$1 done=$2
  shift 2
  finished "$dir" "$done" "$@" && return 0
  if [ -f "$dir/$done" ]; then
    echo "$(basename "$0"): $dir was made by another command line (see its command.txt); use another OUT, or delete $dir" >&2
    exit 1
  fi
  rm -rf "$dir"
  local t0=$SECONDS
  "$@"
  printf '%s\n' "$@" >"$dir/command.txt.tmp"
  mv "$dir/command.txt.tmp" "$dir/command.txt"
  printf 'seconds %s\nfinished %s\ncommit %s\ncpu %s\n' $((SECONDS - t0)) "$(date -u +%Y-%m-%dT%H:%M:%SZ)" \
    "$(git rev-parse --short HEAD 2>/dev/null || echo unknown)" "$(cpu_line)" >"$dir/step.txt"
  echo "$(basename "$0"): $dir: $((SECONDS - t0)) s" >&2
}
