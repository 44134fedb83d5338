# Shared by the resumable benchmark scripts (bench/panoptic_rig.sh, bench/pool_select.sh).
#
# step DIR DONE COMMAND...: runs COMMAND (whose output folder is DIR) unless DIR/DONE exists
# and DIR/command.txt holds the same command line; a finished step made by another command
# line is refused. The model a step reads is part of its identity through the step that
# made it. Prints how long a step that ran took (seconds) to stderr and writes it, with the
# time it finished (UTC), the commit of the checkout that ran it and the CPU (cpu_line), to
# DIR/step.txt. A caller may set the array STEP_RUNNER to a prefix the command runs under
# (bench/pool_select.sh --jobs: `taskset -c CORE`); it is not part of the command line.
#
# hold_instruction_set STEP_TXT: continues records made on another instruction set on it.
#
# finished DIR DONE COMMAND...: whether step would reuse DIR (without running anything).
finished() {
  local dir=$1 done=$2
  shift 2
  [ -f "$dir/$done" ] && [ "$(cat "$dir/command.txt" 2>/dev/null)" = "$(printf '%s\n' "$@")" ]
}
# The machine a step ran on, as far as its numbers depend on it: the CPU's name, core count
# and the instruction set fillgs's kernels ran on (AVX2 and AVX-512 round differently, so
# the same command trains different models on each): the CPU's widest, or the one
# FILLGS_INSTRUCTION_SET held them to.
cpu_widest() {
  local simd=sse4
  grep -qw avx2 /proc/cpuinfo 2>/dev/null && simd=avx2
  grep -qw avx512f /proc/cpuinfo 2>/dev/null && simd=avx512
  echo $simd
}
cpu_line() {
  local name simd held=${FILLGS_INSTRUCTION_SET:-}
  name=$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo 2>/dev/null | head -1)
  simd=$(cpu_widest)
  if [ -n "$held" ] && [ "$held" != native ] && [ "$held" != "$simd" ]; then
    echo "${name:-unknown}, $(nproc) cores, $held (a CPU with $simd, held to $held by FILLGS_INSTRUCTION_SET)"
  else
    echo "${name:-unknown}, $(nproc) cores, $simd"
  fi
}
# hold_instruction_set STEP_TXT: a benchmark continued from records made on another
# instruction set runs every step on the recorded one (FILLGS_INSTRUCTION_SET), so that a
# model trained again is the recorded model; one line says so. Nothing when STEP_TXT is
# missing, records this CPU's widest, or FILLGS_INSTRUCTION_SET is already set.
hold_instruction_set() {
  local recorded
  recorded=$(sed -n 's/^cpu [^,]*, [^,]*, \([a-z0-9]*\).*/\1/p' "$1" 2>/dev/null || true)
  [ -n "$recorded" ] && [ -z "${FILLGS_INSTRUCTION_SET:-}" ] && [ "$recorded" != "$(cpu_widest)" ] || return 0
  export FILLGS_INSTRUCTION_SET=$recorded
  echo "$(basename "$0"): $1 ran on $recorded and this CPU has $(cpu_widest): every step runs with FILLGS_INSTRUCTION_SET=$recorded" >&2
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
  ${STEP_RUNNER[@]+"${STEP_RUNNER[@]}"} "$@"
  printf '%s\n' "$@" >"$dir/command.txt.tmp"
  mv "$dir/command.txt.tmp" "$dir/command.txt"
  printf 'seconds %s\nfinished %s\ncommit %s\ncpu %s\n' $((SECONDS - t0)) "$(date -u +%Y-%m-%dT%H:%M:%SZ)" \
    "$(git rev-parse --short HEAD 2>/dev/null || echo unknown)" "$(cpu_line)" >"$dir/step.txt"
  echo "$(basename "$0"): $dir: $((SECONDS - t0)) s" >&2
}
