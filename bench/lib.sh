# Shared by the resumable benchmark scripts (bench/panoptic_rig.sh, bench/pool_select.sh).
#
# step DIR DONE COMMAND...: runs COMMAND (whose output folder is DIR) unless DIR/DONE exists
# and DIR/command.txt holds the same command line; a finished step made by another command
# line is refused. The model a step reads is part of its identity through the step that
# made it. Prints how long a step that ran took (seconds) to stderr and writes it, with the
# time it finished (UTC) and the commit of the checkout that ran it, to DIR/step.txt.
#
# finished DIR DONE COMMAND...: whether step would reuse DIR (without running anything).
finished() {
  local dir=$1 done=$2
  shift 2
  [ -f "$dir/$done" ] && [ "$(cat "$dir/command.txt" 2>/dev/null)" = "$(printf '%s\n' "$@")" ]
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
  printf 'seconds %s\nfinished %s\ncommit %s\n' $((SECONDS - t0)) "$(date -u +%Y-%m-%dT%H:%M:%SZ)" \
    "$(git rev-parse --short HEAD 2>/dev/null || echo unknown)" >"$dir/step.txt"
  echo "$(basename "$0"): $dir: $((SECONDS - t0)) s" >&2
}
