#!/usr/bin/env bash
# Time-blocked stepping from the command line (time.block_steps; tests/test_window.c checks the bits): a numerical
# fault inside a window stops the run with the message, time and partial result of stepping one step at a time, on
# a ring and on a corridor (the faulting vehicle enters inside a window); a windowed ring and a windowed corridor
# interrupted by SIGTERM and resumed on the other thread count give the uninterrupted run's bytes; bad values are
# refused with exit status 2, the key named and no file written.
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
PY=/usr/bin/python3
tmp=$(mktemp -d)
. tests/interrupt.sh
trap 'rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

# A fault: one vehicle of 600 (3 blocks: windows of 16 steps on one thread) returns NaN above 5 m/s.
if cc -std=c11 -O1 -fPIC -shared -Iinclude tests/data/nan_plugin.c -o "$tmp/nan_plugin.so" -lm 2>"$tmp/cc.log"; then
  printf 'road: {length_m: 9000}\ntime: {duration_s: 60, dt_s: 0.1}\nfleet:\n  vehicles: 600\n  classes: [{class: midsize_sedan, count: 600}]\n  drivers:\n    - {model: idm, count: 599}\n    - {model: plugin, path: nan_plugin.so, placement: explicit, indices: [300]}\ninitial: {state: rest}\n' > "$tmp/nan.yaml"
  m1=$($BIN run "$tmp/nan.yaml" -q -o "$tmp/n1.h5" --set time.block_steps=1 2>&1); r1=$?
  m16=$($BIN run "$tmp/nan.yaml" -q -o "$tmp/n16.h5" --set time.block_steps=16 2>&1); r16=$?
  if [ $r1 -eq 1 ] && [ $r16 -eq 1 ] && echo "$m16" | grep -q "numerical fault at t = .*vehicle 300 " &&
     [ "$m1" = "$(echo "$m16" | sed "s#n16.h5#n1.h5#g")" ] &&
     $PY - "$tmp/n1.h5.partial" "$tmp/n16.h5.partial" <<'PY'
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1]), h5py.File(sys.argv[2])
for k in ("timeseries/t", "timeseries/mean_speed", "meta/steps_done"):
    assert np.asarray(a[k][()]).tobytes() == np.asarray(b[k][()]).tobytes(), k
assert a["meta/steps_done"][()] > 16, a["meta/steps_done"][()]
PY
  then ok fault_inside_window_as_per_step; else ko fault_inside_window_as_per_step "rc=$r1/$r16: $m1 | $m16"; fi
else
  ko fault_inside_window_as_per_step "cannot build the test plugin: $(cat "$tmp/cc.log")"
fi

# The same on a corridor: vehicle 500 of a 30 km corridor (about 500 on the road: windows of 16 steps) returns NaN
# as it enters, inside a window.
if [ -e "$tmp/nan_plugin.so" ]; then
  printf 'road: {type: corridor, length_m: 30000}\ntime: {duration_s: 2000, dt_s: 0.1}\nfleet:\n  placement: interleaved\n  classes: [{class: midsize_sedan, fraction: 1}]\n  drivers:\n    - {model: idm, fraction: 0.999, noise_mps2: 0.2}\n    - {model: plugin, path: nan_plugin.so, fraction: 0.001}\ncorridor:\n  inflow: {flow_vph: 3300}\n' > "$tmp/nanc.yaml"
  m1=$($BIN run "$tmp/nanc.yaml" -q -o "$tmp/c1.h5" --set time.block_steps=1 2>&1); r1=$?
  m16=$($BIN run "$tmp/nanc.yaml" -q -o "$tmp/c16.h5" --set time.block_steps=16 2>&1); r16=$?
  if [ $r1 -eq 1 ] && [ $r16 -eq 1 ] && echo "$m16" | grep -q "numerical fault at t = 763.9 s: vehicle 500 " &&
     [ "$m1" = "$(echo "$m16" | sed "s#c16.h5#c1.h5#g")" ] &&
     $PY tests/h5same.py "$tmp/c1.h5.partial" "$tmp/c16.h5.partial" >/dev/null
  then ok corridor_fault_inside_window_as_per_step; else ko corridor_fault_inside_window_as_per_step "rc=$r1/$r16: $m1 | $m16"; fi
fi

# Interrupted and resumed: 5000 vehicles (windows split between 2 threads), SIGTERM after a checkpoint, resumed on
# one thread.
S=tests/data/tiny_ring.yaml
L="--set fleet.vehicles=5000 --set road.length_m=100000 --set time.duration_s=4000 --set output.trajectories=false"
$BIN run $S -q -o "$tmp/ref.h5" $L --threads 1 --set time.block_steps=1
$BIN run $S -q -o "$tmp/r.h5" $L --threads 2 --checkpoint-every 0.2 & pid=$!
wait_checkpoint "$tmp/r.h5" $pid; signal_running TERM $pid; wait $pid; rc=$?
if [ $rc -eq 3 ] && $BIN run --resume "$tmp/r.h5" -q --threads 1 && $PY - "$tmp/ref.h5" "$tmp/r.h5" <<'PY'
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1]), h5py.File(sys.argv[2])
names = []
a.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) and not n.startswith("meta/") else None)
raw = lambda x: np.asarray(x).tobytes() if np.asarray(x).dtype.kind in "fiu" else np.asarray(x).tolist()
bad = [n for n in names if raw(a[n][()]) != raw(b[n][()])]
assert len(names) > 50 and not bad, bad
assert b["meta/completed"][()] == 1
PY
then ok resume_windows_bit_identical; else ko resume_windows_bit_identical "rc=$rc"; fi

# A corridor in windows of 16 steps on two threads (tests/data/corridor_resume.yaml: a controller with memory,
# detectors, Edie cells, trajectories, a virtual leader), SIGTERM after a checkpoint, resumed on one thread: the
# bytes of one step at a time.
C=tests/data/corridor_resume.yaml
LC="--set time.duration_s=9000 --set seed=23"
$BIN run $C -q -o "$tmp/cref.h5" $LC --threads 1 --set time.block_steps=1
$BIN run $C -q -o "$tmp/c.h5" $LC --threads 2 --set time.block_steps=16 --checkpoint-every 0.2 & pid=$!
wait_checkpoint "$tmp/c.h5" $pid; signal_running TERM $pid; wait $pid; rc=$?
if [ $rc -eq 3 ] && $BIN run --resume "$tmp/c.h5" -q --threads 1 && $PY tests/h5same.py "$tmp/cref.h5" "$tmp/c.h5" >/dev/null
then ok corridor_resume_windows_bit_identical; else ko corridor_resume_windows_bit_identical "rc=$rc"; fi

# Refusals: exit 2, the key named, no file.
bad() { # name, expected text, --set assignment, [scenario]
  local msg rc
  msg=$($BIN run "${4:-$S}" -q -o "$tmp/bad.h5" --set "$3" 2>&1); rc=$?
  if [ $rc -eq 2 ] && echo "$msg" | grep -q -- "$2" && [ ! -e "$tmp/bad.h5" ] && [ ! -e "$tmp/bad.h5.partial" ]
  then ok "$1"; else ko "$1" "rc=$rc $msg"; fi
}
bad block_steps_too_many "time.block_steps" "time.block_steps=201"
bad block_steps_negative "time.block_steps" "time.block_steps=-1"
bad tile_vehicles_negative "time.tile_vehicles" "time.tile_vehicles=-5"
