#!/usr/bin/env bash
# Corridor vs ring (issue 16): vehicle-steps per second of a corridor holding about N vehicles and of a ring of N
# vehicles, same drivers and step, 1 and 2 threads, for each binary given (default: this tree's bin/wavefuel), e.g.
#   bench/corridor_vs_ring/run.sh --bin main=/tmp/wavefuel_main --bin this=bin/wavefuel
# Options of run.py: --threads 1,2 --length-m 150000 --fill-s 5000 --window-s 1000.
set -eu
cd "$(dirname "$0")/../.."
make --no-print-directory -j2 bin/wavefuel >/dev/null
exec /usr/bin/python3 bench/corridor_vs_ring/run.py "$@"
