# Sourced by the shell tests that run wavefuel and check its results (BIN set before): a temporary directory $tmp
# removed on exit with any background runs left in pids, the interrupt helpers (tests/interrupt.sh), and the
# PASS / FAIL lines tests/run.sh counts.
tmp=$(mktemp -d)
pids=()
trap 'for p in "${pids[@]}"; do kill -KILL "$p" 2>/dev/null; done; rm -rf "$tmp"' EXIT
. tests/interrupt.sh
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }
# check NAME CMD...: PASS with the command's account, or FAIL with its reason.
check() {
  local name=$1 msg; shift
  if msg=$("$@" 2>&1); then ok "$name ($msg)"; else ko "$name" "$msg"; fi
}
run() { $BIN run "$@" -q --force; }
