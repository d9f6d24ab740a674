#!/usr/bin/env bash
# Runs every test program (BUILD/tests/test_*), one full `wavefuel run` of tests/data/tiny_ring.yaml, the bad-
# input error paths of `wavefuel run` and `wavefuel energy`, and the fuzz corpus replays under
# valgrind --leak-check=full --error-exitcode=1. Prints "PASS name" / "FAIL name" per program and the totals;
# exits 1 if any program has a memory error or a leak. Build first (make tests); see docs/reliability.md.
# Definite, indirect and possible leaks count; libgomp's idle worker threads (their TLS blocks show as "possibly
# lost") are suppressed by tools/valgrind.supp. A test that fails on its own (exit != expected, clean valgrind
# log) is reported as a test failure, not a memory error.
set -u
cd "$(dirname "$0")/.." || exit 1
BUILD=${BUILD:-build}
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
command -v valgrind >/dev/null 2>&1 || ./tools/install-deps.sh valgrind || exit 1
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-2}
export WAVEFUEL_VEHICLES=
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export TMPDIR="$tmp" # the fuzz targets' scratch directories (an aborting input leaves its own behind)
VG=(valgrind --leak-check=full --show-leak-kinds=definite,indirect,possible
    --errors-for-leak-kinds=definite,indirect,possible --error-exitcode=1 --track-origins=yes -q
    --suppressions=tools/valgrind.supp)
pass=0; fail=0
# vg NAME EXPECTED_STATUS COMMAND...: the program's own status must be EXPECTED_STATUS (valgrind reports
# errors with status 1 only when the program would not already exit 1: see the log check below).
vg() {
  local name=$1 want=$2; shift 2
  local log="$tmp/$name.vg"
  "${VG[@]}" --log-file="$log" "$@" >"$tmp/$name.out" 2>&1 </dev/null
  local rc=$?
  if [ -s "$log" ]; then
    fail=$((fail + 1)); echo "FAIL $name: valgrind errors (exit $rc)"
    sed 's/^/    /' "$log" | head -40
  elif [ "$rc" -ne "$want" ]; then
    fail=$((fail + 1)); echo "FAIL $name: exit $rc, expected $want; valgrind log clean (a test failure, not a memory error)"
    grep -E '^FAIL|check failed' "$tmp/$name.out" | head -5 | sed 's/^/    /'
  else
    pass=$((pass + 1)); echo "PASS $name"
  fi
}
for t in "$BUILD"/tests/test_*; do
  [ -x "$t" ] || continue
  case "$t" in *.d|*.o) continue ;; esac
  vg "$(basename "$t")" 0 "$t"
done
vg run_tiny_ring 0 "$BIN" run tests/data/tiny_ring.yaml -o "$tmp/tiny.h5" -q
[ -f "$tmp/tiny.h5" ] || { fail=$((fail + 1)); echo "FAIL run_tiny_ring_result (no result file)"; }
# Error paths free everything too: a scenario error after the vehicle classes are loaded, and a CSV error.
vg run_error_path 2 "$BIN" run tests/data/tiny_ring.yaml -o "$tmp/bad.h5" -q --set "fleet.drivers[0].params.T_s=-1"
printf 'v,a,theta\n10,0.5,0\n10,nan,0\n' > "$tmp/bad.csv"
vg energy_error_path 2 "$BIN" energy --class midsize_sedan "$tmp/bad.csv"
for t in scenario vehicle csv; do
  drv="$BUILD/fuzz/${t}_replay"
  [ -x "$drv" ] || continue
  # The seeds and the fixed crash regressions (open-* ones still abort by design: tests/t_fuzz_smoke.sh).
  files=("fuzz/corpus/$t"/*)
  for f in fuzz/crashes/$t/*; do case "$(basename "$f")" in open-*) ;; *) [ -f "$f" ] && files+=("$f") ;; esac; done
  vg "replay_$t" 0 "$drv" "${files[@]}"
done
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
