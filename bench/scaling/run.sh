#!/usr/bin/env bash
# Scaling benchmark (issue 8): builds bin/wavefuel and build/bench/stream_triad, then runs bench/scaling/run.py,
# which sets fleet.vehicles, road.length_m and time.duration_s of bench/scaling/ring.yaml for each N and writes
# bench/scaling/results.json, results.csv and the Markdown tables. Arguments go to run.py (see its --help), e.g.
#   bench/scaling/run.sh --repeats-large 1        bench/scaling/run.sh --table
set -eu
cd "$(dirname "$0")/../.."
make --no-print-directory -j2 all build/bench/stream_triad >/dev/null
exec /usr/bin/python3 bench/scaling/run.py "$@"
