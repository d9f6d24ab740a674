#!/usr/bin/env bash
# Safety filters (docs/controllers.md#safety-filters) through `wavefuel run`:
# 1. a scripted leader brakes hard in front of a scripted follower (examples/plugins/scripted_accel.c) on a ring:
#    without a filter the follower collides (overlap repairs, the summary's warning line); with the Gipps filter it
#    does not, and every step's applied acceleration and the intervention count equal a recomputation here, from
#    the recorded trajectories (every step) with the documented rule and formula in numpy;
# 2. the issue's acceptance case: PI with saturation at 10 % on the corridor bottleneck (bench/sparse_control)
#    repairs overlaps without the filter and none with it; interventions in /summary, the printed summary and the
#    Python summary, and the new /summary datasets only in the filtered run;
# 3. a corridor and a ring with a filter interrupted by SIGTERM and resumed: bit-identical to uninterrupted runs.
set -u
cd "$(dirname "$0")/.." || exit 1
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
BUILD=${BUILD:-build}
PY=/usr/bin/python3
SO="$(pwd)/$BUILD/plugins/scripted_accel.so"
tmp=$(mktemp -d)
pids=()
trap 'for p in "${pids[@]}"; do kill -KILL "$p" 2>/dev/null; done; rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }
if [ ! -f "$SO" ]; then echo "FAIL safety_plugin: $SO missing: run make tests"; exit 1; fi

# ------------------------------------------------------------------ 1. scripted hard braking
# Vehicle 0 (follower, group av) accelerates at 2 m/s^2 for 10 s, then holds its speed; vehicle 1 (its leader)
# accelerates at 1 m/s^2 for 10 s, then brakes at 8 m/s^2 until it stops. Both start at rest 100 m apart.
write_ring() { # file, safety line
  cat >"$1" <<EOF
name: scripted_braking
road: {length_m: 200}
time: {duration_s: 30, dt_s: 0.1, output_interval_s: 0.1}
fleet:
  vehicles: 2
  placement: explicit
  classes: [{class: midsize_sedan, indices: [0, 1]}]
  drivers:
    - {name: av, model: plugin, path: $SO, indices: [0], params: {a1_mps2: 2, n1_steps: 100}$2}
    - {name: lead, model: plugin, path: $SO, indices: [1], params: {a1_mps2: 1, n1_steps: 100, a2_mps2: -8, n2_steps: 300}}
initial: {state: rest}
output: {trajectories: true, trajectory_interval_s: 0.1}
EOF
}
write_ring "$tmp/free.yaml" ""
write_ring "$tmp/safe.yaml" ", safety: {kind: gipps, decel_mps2: 4, leader_decel_mps2: 6, gap_min_m: 2}"
out_free=$($BIN run "$tmp/free.yaml" -o "$tmp/free.h5" 2>&1) || ko scripted_run_free "$out_free"
out_safe=$($BIN run "$tmp/safe.yaml" -o "$tmp/safe.h5" 2>&1) || ko scripted_run_safe "$out_safe"
if printf '%s' "$out_free" | grep -q "^warning: [1-9][0-9]* overlap repairs\?: these results include repaired collisions" &&
   ! printf '%s' "$out_free" | grep -q "^safety filter"; then ok scripted_unfiltered_collides_and_warns
else ko scripted_unfiltered_collides_and_warns "$out_free"; fi
if ! printf '%s' "$out_safe" | grep -q "^warning" &&
   printf '%s' "$out_safe" | grep -q "^safety filter gipps, group av: vehicle-steps 300 | interventions [1-9]"; then
  ok scripted_filtered_summary_line
else ko scripted_filtered_summary_line "$out_safe"; fi
# `wavefuel info` of the result warns as the run did (the same line), and not for the filtered run.
info_free=$($BIN info "$tmp/free.h5" 2>&1); info_safe=$($BIN info "$tmp/safe.h5" 2>&1)
if [ "$(printf '%s\n' "$info_free" | grep '^warning')" = "$(printf '%s\n' "$out_free" | grep '^warning')" ] &&
   printf '%s' "$info_free" | grep -q "^warning: [1-9]" && ! printf '%s' "$info_safe" | grep -q "^warning"
then ok info_warns_of_repairs; else ko info_warns_of_repairs "$info_free"; fi
if msg=$($PY - "$tmp/free.h5" "$tmp/safe.h5" <<'PY' 2>&1
import sys, h5py, numpy as np
free, safe = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
assert free["summary/overlaps"][()] > 0, "the unfiltered follower should collide"
assert "collisions_repaired" not in free["summary"] and "group_safety_interventions" not in free["summary"]
s = safe["summary"]
assert s["overlaps"][()] == 0 and s["collisions_repaired"][()] == 0, (s["overlaps"][()], s["collisions_repaired"][()])
tr = safe["trajectories"]
x, v, a = tr["x"][()], tr["v"][()], tr["a"][()]
L = 4.9  # midsize_sedan length (vehicles/midsize_sedan.yaml)
dt, b, bh, s0, dmax = 0.1, 4.0, 6.0, 2.0, 9.0
n = x.shape[0] - 1                     # the last frame is the final instant: no step
gap, vf, vl = x[:n, 1] - L - x[:n, 0], v[:n, 0], v[:n, 1]
raw = np.where(np.arange(n) < 100, 2.0, 0.0)   # the follower's script, within its limits [-9, 5]
rad = b * b * dt * dt + b * (2 * (gap - s0) - vf * dt + vl ** 2 / bh)
vsafe = np.maximum(0.0, -b * dt + np.sqrt(np.maximum(rad, 0.0)))
bound = (vsafe - vf) / dt
want = np.where(raw > bound, np.maximum(bound, -dmax), raw)
err = np.max(np.abs(a[:n, 0] - want))
assert err < 1e-9, f"applied accelerations differ from the rule by {err:g}"
hits = int(np.sum(want < raw))
got = int(s["group_safety_interventions"][0])
assert got == hits and hits > 10, (got, hits)
assert int(s["group_safety_steps"][0]) == n and int(s["group_safety_steps"][1]) == 0
assert int(s["safety_interventions"][()]) == hits and abs(s["group_safety_share"][0] - hits / n) < 1e-15
assert np.all(gap > 0), gap.min()
print(f"{hits} interventions in {n} steps, min gap {gap.min():.3f} m")
PY
); then ok "scripted_count_against_recomputation ($msg)"; else ko scripted_count_against_recomputation "$msg"; fi

# ------------------------------------------------------------------ 2. acceptance: PI with saturation, 10 %
B=bench/sparse_control/corridor_bottleneck.yaml
PI="--set fleet.drivers[0].fraction=0.9 --set fleet.drivers[1].fraction=0.1 --set fleet.drivers[1].model=pi_saturation --set seed=1"
o0=$($BIN run $B -o "$tmp/pi.h5" $PI 2>&1) || ko pi_run "$o0"
o1=$($BIN run $B -o "$tmp/pi_safe.h5" $PI --set 'fleet.drivers[1].safety.kind=gipps' 2>&1) || ko pi_safe_run "$o1"
if msg=$($PY - "$tmp/pi.h5" "$tmp/pi_safe.h5" <<'PY' 2>&1
import sys, h5py
a, b = h5py.File(sys.argv[1], "r")["summary"], h5py.File(sys.argv[2], "r")["summary"]
assert a["overlaps"][()] > 0, a["overlaps"][()]
assert b["overlaps"][()] == 0 and b["collisions_repaired"][()] == 0
assert b["group_safety_interventions"][1] > 0 and b["group_safety_interventions"][0] == 0
assert b["safety_interventions"][()] == b["group_safety_interventions"][1]
added = sorted(set(b) - set(a))
assert added == ["collisions_repaired", "group_safety_interventions", "group_safety_share", "group_safety_steps",
                 "safety_interventions"], added
print(f"{a['overlaps'][()]} overlap repairs without the filter, 0 with it; {b['safety_interventions'][()]} interventions")
PY
); then ok "pi_saturation_10pct_no_overlaps_with_filter ($msg)"; else ko pi_saturation_10pct_no_overlaps_with_filter "$msg"; fi
if printf '%s' "$o0" | grep -q "^warning: .* overlap repairs: these results include repaired collisions" &&
   printf '%s' "$o1" | grep -q "^safety filter gipps, group av: vehicle-steps [0-9]* | interventions [1-9][0-9]* | share" &&
   ! printf '%s' "$o1" | grep -q "^warning"; then ok pi_saturation_printed_summary
else ko pi_saturation_printed_summary "$o0 // $o1"; fi
# The Python summary of the same run (the library of `make python`, when built).
if [ -f lib/libwavefuel.so ]; then
  if msg=$(PYTHONPATH=python WAVEFUEL_LIB=lib/libwavefuel.so $PY - "$tmp/pi_safe.h5" $PI --set 'fleet.drivers[1].safety.kind=gipps' <<'PY' 2>&1
import sys, h5py, wavefuel
sets = dict(a.split("=", 1) for a in sys.argv[2:] if a != "--set")
sim = wavefuel.Simulation(wavefuel.Scenario.load("bench/sparse_control/corridor_bottleneck.yaml", overrides=sets))
s = sim.run()
f = h5py.File(sys.argv[1], "r")["summary"]
assert s["collisions_repaired"].value == 0 and s["safety_interventions"].value == f["safety_interventions"][()]
assert s["groups"]["av"]["group_safety_interventions"].value == f["group_safety_interventions"][1]
assert s["groups"]["human"]["group_safety_steps"].value == 0
print(s["groups"]["av"]["group_safety_interventions"].value)
PY
  ); then ok "python_summary_groups ($msg)"; else ko python_summary_groups "$msg"; fi
else
  ok "python_summary_groups (skipped: lib/libwavefuel.so not built; make python)"
fi

# ------------------------------------------------------------------ 3. resume with a filter
cat >"$tmp/compare.py" <<'PY'
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
skip = {"meta/wall_time_s", "meta/start_time", "meta/threads", "meta/phase_time"}
def objs(f):
    d = {}
    f.visititems(lambda n, o: d.__setitem__(n, o) if isinstance(o, h5py.Dataset) else None)
    return d
oa, ob = objs(a), objs(b)
assert set(oa) == set(ob), sorted(set(oa) ^ set(ob))
def raw(x):
    x = np.asarray(x)
    return (x.dtype.str, x.shape, x.tobytes()) if x.dtype.kind in "fiub" else (x.shape, x.tolist())
bad = [n for n in oa if n not in skip and raw(oa[n][()]) != raw(ob[n][()])]
assert not bad, bad
assert b["summary/safety_interventions"][()] > 0
PY
. tests/interrupt.sh
resume_case() { # name, scenario, args...
  local name=$1 s=$2; shift 2
  $BIN run "$s" -q -o "$tmp/$name.ref.h5" "$@" || { ko "$name" "reference run"; return; }
  $BIN run "$s" -q -o "$tmp/$name.h5" "$@" --checkpoint-every 0.1 2>/dev/null & pid=$!
  pids+=("$pid")
  if ! wait_checkpoint "$tmp/$name.h5" $pid || ! signal_running TERM $pid; then
    wait $pid; ko "$name" "the run ended before a checkpoint"; return; fi
  wait $pid; local rc=$?
  if [ $rc -eq 3 ] && $BIN run --resume "$tmp/$name.h5" -q --threads 1 &&
     msg=$($PY "$tmp/compare.py" "$tmp/$name.ref.h5" "$tmp/$name.h5" 2>&1); then ok "$name"
  else ko "$name" "rc=$rc ${msg:-}"; fi
}
resume_case corridor_safety_resume_bit_identical tests/data/corridor_resume.yaml --set time.duration_s=9000 \
  --set 'fleet.drivers[1].safety.kind=gipps' --set 'fleet.drivers[0].safety.kind=ttc'
resume_case ring_safety_resume_bit_identical tests/data/tiny_ring.yaml --set time.duration_s=5000 \
  --set fleet.vehicles=2000 --set road.length_m=40000 --set output.trajectories=false \
  --set 'fleet.drivers[0].safety.kind=ttc' --set 'fleet.drivers[0].safety.ttc_s=6'
