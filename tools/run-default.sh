#!/usr/bin/env bash
# `make run`: simulates the default scenario (scenarios/ring_mixed_fleet.yaml) into a new, time-stamped result
# file, so repeated runs never overwrite an earlier result, and says where it is.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p output
out="output/ring_mixed_fleet_$(date -u +%Y%m%dT%H%M%SZ).h5"
./bin/wavefuel run scenarios/ring_mixed_fleet.yaml -o "$out"
echo
echo "Result written to $out"
echo "  summary:   ./bin/wavefuel info $out"
echo "  a figure:  ./bin/wavefuel run scenarios/sugiyama.yaml -o output/sugiyama.h5 && /usr/bin/python3 tools/plot_timespace.py output/sugiyama.h5"
