#!/usr/bin/env bash
# The hand-written kernels' narrower forms on a machine whose runs take a wider one: the bitwise checks of
# tests/test_energy.c with WAVEFUEL_SIMD=2 (2 lanes, every x86-64) and WAVEFUEL_SIMD=4 (4 lanes, AVX2) forcing the
# narrower energy and noise kernels, tests/test_select.c's with the gather's plain loop, tests/test_rng.c's with the
# plain Philox (rings drawn together against their own blocks); and one engine run whose
# fleet fuel must agree to the last bit between the CPU's widest form and each narrower one (the noise's Philox too:
# plain at 2 lanes, 8 counters at once at AVX2). (Where the CPU's widest is 4 lanes, the =4 run repeats the default.)
set -u
cd "$(dirname "$0")/.."
BUILD=${BUILD:-build}
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
args=(run scenarios/ring_mixed_fleet.yaml -q --set time.duration_s=60 --set time.warmup_s=10)
"$BIN" "${args[@]}" -o "$tmp/wide.h5" >/dev/null 2>&1
for lanes in 2 4; do
    for t in test_energy test_select test_rng; do
        WAVEFUEL_SIMD=$lanes "$BUILD/tests/$t" | sed -n "s/^\(PASS\|FAIL\) /\1 simd${lanes}_/p"
    done
    WAVEFUEL_SIMD=$lanes "$BIN" "${args[@]}" -o "$tmp/narrow$lanes.h5" >/dev/null 2>&1
    if h5diff -q "$tmp/wide.h5" "$tmp/narrow$lanes.h5" /vehicles/fuel &&
        h5diff -q "$tmp/wide.h5" "$tmp/narrow$lanes.h5" /timeseries/fuel_rate
    then echo "PASS simd_widths_same_fleet_fuel_$lanes"; else echo "FAIL simd_widths_same_fleet_fuel_$lanes"; fi
done
