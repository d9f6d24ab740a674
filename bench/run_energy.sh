#!/usr/bin/env bash
# Builds and runs the CIRCLES energy-model benchmark (bench/bench_energy.c) and prints its table, preceded by
# the machine, compiler and load it ran on (the figures mean little without them). Arguments are passed to the
# benchmark (default 1e7 points). Usage: bench/run_energy.sh [N_POINTS]
set -eu
cd "$(dirname "$0")/.."
BUILD=${BUILD:-build}
make --no-print-directory BUILD="$BUILD" "$BUILD/bench/bench_energy" >/dev/null
cpu=$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -1)
echo "# $(date -u +%Y-%m-%dT%H:%MZ)  $(uname -m), $(nproc) cores, ${cpu:-unknown CPU}"
echo "# $(${CC:-gcc} --version | head -1); load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
"$BUILD/bench/bench_energy" "$@"
echo "# load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
