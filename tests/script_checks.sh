# Sourced by the command-line test scripts: a scratch folder removed on exit (in $work, the
# current directory) and `check NAME CONDITION-COMMAND...`, which counts failures in $fails.
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work" || exit 1
fails=0
check() {
  local name=$1; shift
  if "$@"; then echo "ok   $name"; else echo "FAIL $name"; fails=$((fails + 1)); fi
}
