# Shared by the resumable benchmark scripts (bench/panoptic_rig.sh, bench/pool_select.sh).
#
# step DIR DONE COMMAND...: runs COMMAND (whose output folder is DIR) unless DIR/DONE exists
# and DIR/command.txt holds the same command line; a finished step made by another command
# line is refused. The model a step reads is part of its identity through the step that
# made it. Prints how long a step that ran took (seconds) to stderr and writes it, with the
# time it finished (UTC), to DIR/step.txt.
step() {
  local dir=$1 done=$2
  shift 2
  local want
  want=$(printf '%s\n' "$@")
  if [ -f "$dir/$done" ]; then
    if [ "$(cat "$dir/command.txt" 2>/dev/null)" = "$want" ]; then return 0; fi
    echo "$(basename "$0"): $dir was made by another command line (see its command.txt); use another OUT, or delete $dir" >&2
    exit 1
  fi
  rm -rf "$dir"
  local t0=$SECONDS
  "$@"
  printf '%s\n' "$want" >"$dir/command.txt.tmp"
  mv "$dir/command.txt.tmp" "$dir/command.txt"
  printf 'seconds %s\nfinished %s\n' $((SECONDS - t0)) "$(date -u +%Y-%m-%dT%H:%M:%SZ)" >"$dir/step.txt"
  echo "$(basename "$0"): $dir: $((SECONDS - t0)) s" >&2
}
