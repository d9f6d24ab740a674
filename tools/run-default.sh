#!/usr/bin/env bash
# `make run`: evaluates the six classes at a few cruise points (until the simulator's default scenario exists).
set -euo pipefail
cd "$(dirname "$0")/.."
for c in compact_sedan midsize_sedan midsize_suv midsize_pickup class4_pnd class8_tractor; do
  echo "== $c: fuel at 10, 20, 30 m/s on a flat road =="
  printf 'v,a,theta\n10,0,0\n20,0,0\n30,0,0\n' | ./bin/wavefuel energy --class "$c"
done
