#!/usr/bin/env bash
# The energy kernel's 2-lane form (every x86-64) on a machine whose runs take the 4-lane AVX2 form: the same
# bitwise checks of tests/test_energy.c, with WAVEFUEL_SIMD=2 forcing the narrower kernel; and one engine run
# whose fleet fuel must agree to the last bit between the two forms.
set -u
cd "$(dirname "$0")/.."
BUILD=${BUILD:-build}
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
WAVEFUEL_SIMD=2 "$BUILD/tests/test_energy" | sed -n 's/^\(PASS\|FAIL\) /\1 simd2_/p'
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
args=(run scenarios/ring_mixed_fleet.yaml -q --set time.duration_s=60 --set time.warmup_s=10)
"$BIN" "${args[@]}" -o "$tmp/wide.h5" >/dev/null 2>&1
WAVEFUEL_SIMD=2 "$BIN" "${args[@]}" -o "$tmp/narrow.h5" >/dev/null 2>&1
if h5diff -q "$tmp/wide.h5" "$tmp/narrow.h5" /vehicles/fuel && h5diff -q "$tmp/wide.h5" "$tmp/narrow.h5" /timeseries/fuel_rate
then echo "PASS simd_widths_same_fleet_fuel"; else echo "FAIL simd_widths_same_fleet_fuel"; fi
