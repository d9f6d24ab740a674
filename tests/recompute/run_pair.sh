#!/usr/bin/env bash
# usage: run_pair.sh NAME SCENARIO.yaml CHECK.py TMPDIR: runs the scenario as written (trajectories every step) and
# without trajectories, then `CHECK.py BIN TRAJ.h5 NOTRAJ.h5 TMPDIR` (tests/recompute/ring.py, corridor.py), whose
# PASS/FAIL lines it passes on; a run that fails is "FAIL NAME_runs".
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
name=$1 scen=$2 check=$3 tmp=$4
if "$BIN" run "$scen" -q -o "$tmp/traj.h5" && "$BIN" run "$scen" -q -o "$tmp/notraj.h5" --set output.trajectories=false
then
  /usr/bin/python3 "$check" "$BIN" "$tmp/traj.h5" "$tmp/notraj.h5" "$tmp"
else
  echo "FAIL ${name}_runs"
fi
