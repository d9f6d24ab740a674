#!/usr/bin/env bash
# Runs every test program (build/tests/test_*) and every shell test (tests/t_*.sh), each of which prints
# "PASS name" / "FAIL name" lines, and ends with the totals line "N passed, N failed".
# A program that crashes or exits non-zero without reporting a FAIL counts as one failure.
set -u
cd "$(dirname "$0")/.."
BUILD=${BUILD:-build}
export WAVEFUEL_BIN=${WAVEFUEL_BIN:-bin/wavefuel}
# The repository's classes and drive cycles, whatever the caller's environment and wherever the binary under test
# was built: for build-san/bin/wavefuel or build-tsan/bin/wavefuel, PREFIX/vehicles and PREFIX/../shared/data do
# not exist (docs/energy.md, the class search path; docs/cycles.md). tests/t_energy_cli.sh checks the PREFIX rule.
export WAVEFUEL_VEHICLES="$PWD/vehicles"
if [ -z "${WAVEFUEL_DATA:-}" ] && [ -d ../shared/data ]; then export WAVEFUEL_DATA="$(cd ../shared/data && pwd)"; fi
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-2}
pass=0; fail=0
log=$(mktemp -d)
trap 'rm -rf "$log"' EXIT
run_one() {
  local name=$1; shift
  local out="$log/$name.out"
  local start=$SECONDS
  "$@" >"$out" 2>&1
  local rc=$?
  local p f
  p=$(grep -c '^PASS ' "$out"); f=$(grep -c '^FAIL ' "$out")
  if [ "$rc" -ne 0 ] && [ "$f" -eq 0 ]; then f=1; echo "FAIL $name (exit $rc)" >>"$out"; fi
  pass=$((pass + p)); fail=$((fail + f))
  printf '%-32s %3d passed, %d failed  (%ds)\n' "$name" "$p" "$f" $((SECONDS - start))
  if [ "$f" -ne 0 ]; then sed 's/^/    /' "$out" | grep -v '^    PASS ' | tail -40; fi
}
for t in "$BUILD"/tests/test_*; do
  [ -x "$t" ] || continue
  case "$t" in *.d|*.o) continue ;; esac
  run_one "$(basename "$t")" "$t"
done
for t in tests/t_*.sh; do
  [ -f "$t" ] || continue
  run_one "$(basename "$t" .sh)" bash "$t"
done
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
