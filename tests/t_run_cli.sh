#!/usr/bin/env bash
# `wavefuel run` and `wavefuel info` end to end: results, refusal to overwrite, interruption, and a table of
# scenario errors that must each give exit status 2, a message with file:line and the key, and no result file.
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
PY=/usr/bin/python3
tmp=$(mktemp -d)
. tests/interrupt.sh
trap 'rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

S=tests/data/tiny_ring.yaml
if $BIN run $S -o "$tmp/a.h5" -q && [ -f "$tmp/a.h5" ] && [ ! -e "$tmp/a.h5.partial" ]; then ok run_writes_result; else ko run_writes_result "no result"; fi

out=$($BIN run $S -o "$tmp/b.h5")
if echo "$out" | grep -q 'class8_tractor' && echo "$out" | grep -q "result: $tmp/b.h5"; then ok summary_table; else ko summary_table "$out"; fi

sum1=$(md5sum "$tmp/a.h5" | cut -d' ' -f1)
err=$($BIN run $S -o "$tmp/a.h5" -q 2>&1); rc=$?
sum2=$(md5sum "$tmp/a.h5" | cut -d' ' -f1)
if [ $rc -eq 2 ] && [ "$sum1" = "$sum2" ] && echo "$err" | grep -q 'exists'; then ok no_silent_overwrite; else ko no_silent_overwrite "rc=$rc $err"; fi
if $BIN run $S -o "$tmp/a.h5" -q --force; then ok force_overwrites; else ko force_overwrites "rc=$?"; fi

info=$($BIN info "$tmp/a.h5")
if echo "$info" | grep -q 'completed *1' && echo "$info" | grep -q 'l_per_100km .*L/100km'; then ok info_prints_summary; else ko info_prints_summary "$info"; fi
if $BIN info "$S" >/dev/null 2>&1; then ko info_rejects_non_hdf5 "accepted a YAML file"; else ok info_rejects_non_hdf5; fi

# Same seed, same bits; --set changes the run and is recorded.
$BIN run $S -o "$tmp/c.h5" -q --set seed=4
if $PY - "$tmp/a.h5" "$tmp/b.h5" "$tmp/c.h5" <<'PY'
import sys, h5py, numpy as np
a, b, c = (h5py.File(p) for p in sys.argv[1:])
assert np.array_equal(a["vehicles/fuel"][:], b["vehicles/fuel"][:]), "same seed differs"
assert not np.array_equal(a["vehicles/fuel"][:], c["vehicles/fuel"][:]), "seed had no effect"
assert c["meta/overrides"][()].decode().strip() == "seed=4"
assert c["meta/seed"][()] == 4
PY
then ok seed_and_overrides; else ko seed_and_overrides "see above"; fi

# The step loop's phase times (read from the clock only when the run writes a result): each is >= 0, the step
# phase's is positive, and together they take no longer than the step loop.
if $PY - "$tmp/a.h5" <<'PY'
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1])
names = [n.decode() for n in f["meta/phase_name"][()]]
t = f["meta/phase_time"][()]
assert len(names) == len(t) and np.all(t >= 0), (names, t)
assert t[names.index("fused_step")] + t[names.index("car_following")] > 0, (names, t)
assert t.sum() <= f["meta/wall_time_s"][()] * 1.001 + 1e-6, (t.sum(), f["meta/wall_time_s"][()])
PY
then ok phase_times; else ko phase_times "see above"; fi

# Every dataset documented in docs/output.md exists with units, and every dataset written is documented.
if $PY - "$tmp/a.h5" docs/output.md <<'PY'
import re, sys, h5py
f = h5py.File(sys.argv[1])
# The ring's table only (the corridor's follows under its own heading; tests/t_units_docs.sh checks both).
ring_table = open(sys.argv[2]).read().split("\n## Every dataset\n", 1)[1].split("\n## ", 1)[0]
doc = set(re.findall(r"^\| `/([^`]+)` \|", ring_table, re.M))
doc = {d for d in doc if "/" in d and not d.startswith("vehicles/param_")}
# Rows of runs with a safety filter only (this run has none): documented, and absent here (tests/t_safety.sh).
safety = set(re.findall(r"^\| `/([^`]+)` \|.*\(runs with a safety filter only\) \|$", ring_table, re.M))
assert len(safety) >= 2, safety
doc -= safety
have = set()
f.visititems(lambda n, o: have.add(n) if isinstance(o, h5py.Dataset) else None)
have = {h for h in have if not h.startswith("classes/params/") and not h.startswith("vehicles/param_")}
missing = doc - have
undocumented = have - doc
assert not missing, f"documented but not written: {sorted(missing)}"
assert not undocumented, f"written but not documented: {sorted(undocumented)}"
assert not safety & have, f"written without a safety filter: {sorted(safety & have)}"
for n in have:
    assert "units" in f[n].attrs, f"{n} has no units"
    assert "description" in f[n].attrs, f"{n} has no description"
n = f["vehicles/fuel"].shape[0]
assert n == 22 and f["trajectories/v"].shape == (21, 22), f["trajectories/v"].shape
assert abs(f["summary/fuel"][()] - f["vehicles/fuel"][:].sum()) < 1e-9 * f["summary/fuel"][()]
assert f["meta/completed"][()] == 1
PY
then ok hdf5_round_trip_documented; else ko hdf5_round_trip_documented "see above"; fi

# SIGTERM: the run stops at the end of a step, keeps a readable partial file marked incomplete, exits 3.
$BIN run $S -o "$tmp/k.h5" -q --set time.duration_s=200000 --set fleet.vehicles=2000 --set road.length_m=40000 \
  --set output.trajectories=false --checkpoint-every 0.2 2>"$tmp/k.err" &
pid=$!
wait_checkpoint "$tmp/k.h5" $pid; signal_running TERM $pid
wait $pid; rc=$?
# The message names the ring's row counters (from the writer's table) and says the run can be resumed.
if [ $rc -eq 3 ] && [ -f "$tmp/k.h5.partial" ] && [ ! -e "$tmp/k.h5" ] &&
   grep -qF "(/meta/reason says why; /meta/timeseries_rows and trajectory_rows count the rows written); resume with --resume" "$tmp/k.err" &&
   $PY - "$tmp/k.h5.partial" <<'PY'
import sys, h5py
f = h5py.File(sys.argv[1])
assert f["meta/completed"][()] == 0
assert "SIGTERM" in f["meta/reason"][()].decode()
assert f["timeseries/t"].shape[0] >= 1 and f["summary/fuel"][()] >= 0
PY
then ok sigterm_leaves_partial; else ko sigterm_leaves_partial "rc=$rc"; fi

# Bad inputs: each must fail with status 2, name the place, and leave nothing behind.
bad() { # name, expected-substring, extra args...
  local name=$1 want=$2; shift 2
  local out="$tmp/bad_$name.h5"
  local msg; msg=$($BIN run "$@" -o "$out" -q 2>&1); local rc=$?
  if [ $rc -eq 2 ] && echo "$msg" | grep -qF -- "$want" && [ ! -e "$out" ] && [ ! -e "$out.partial" ]; then ok "error_$name"
  else ko "error_$name" "rc=$rc msg=$msg"; fi
}
cp $S "$tmp/s.yaml"
sed 's/  vehicles: 22/  vehicels: 22/' $S > "$tmp/typo.yaml"
bad unknown_key_suggests "typo.yaml:12: unknown key 'fleet.vehicels' (did you mean 'vehicles'?)" "$tmp/typo.yaml"
bad wrong_type "--set: time.dt_s: expected a number" "$tmp/s.yaml" --set time.dt_s=fast
bad trailing_garbage "expected a number" "$tmp/s.yaml" --set road.length_m=230m
bad out_of_range "time.dt_s: expected a number in [1e-06, 10] s (got '-1')" "$tmp/s.yaml" --set time.dt_s=-1
bad nan_rejected "expected a number" "$tmp/s.yaml" --set road.length_m=nan
bad cannot_fit "cannot fit on a ring" "$tmp/s.yaml" --set fleet.vehicles=60
bad standstill_gaps "standstill gaps" "$tmp/s.yaml" --set fleet.vehicles=34
bad class_not_found "vehicle class 'hovercraft' not found" "$tmp/s.yaml" --set "fleet.classes[0].class=hovercraft"
bad fractions_sum "class fractions sum to 0.9" "$tmp/s.yaml" --set "fleet.classes[0].fraction=0.4"
bad unknown_model "unknown car-following model 'idn' (known: idm" "$tmp/s.yaml" --set "fleet.drivers[0].model=idn"
bad model_param_range "T_s: expected a number in" "$tmp/s.yaml" --set "fleet.drivers[0].params.T_s=-1.5"
bad model_param_unknown "unknown key 'fleet.drivers[0].params.T'" "$tmp/s.yaml" --set "fleet.drivers[0].params.T=1"
bad dt_vs_output "must be a whole multiple of time.dt_s" "$tmp/s.yaml" --set time.output_interval_s=0.05
bad warmup_too_long "warmup_s" "$tmp/s.yaml" --set time.warmup_s=30
bad set_syntax "expected key.path=value" "$tmp/s.yaml" --set fleet.vehicles
bad set_not_a_list "is not a list" "$tmp/s.yaml" --set "road[0].x=1"
printf 'road:\n  length_m: [1, 2\n' > "$tmp/syntax.yaml"
bad yaml_syntax "syntax.yaml:" "$tmp/syntax.yaml"
sed 's/^  length_m: 230$/  length_m: 230\n  grade: {points: [[0, 0.01], [100, 0.01]]}/' $S > "$tmp/g.yaml"
bad grade_not_closed "does not close on the ring" "$tmp/g.yaml"
bad missing_file "cannot open" "$tmp/nope.yaml"

# Checkpoint and resume: an interrupted run (SIGTERM, or SIGKILL after a checkpoint) resumed with --resume gives
# the same bits as the uninterrupted run in every dataset (wall-clock timings and thread count excepted).
L="--set fleet.vehicles=2000 --set road.length_m=40000 --set time.duration_s=4000 --set output.trajectory_interval_s=10"
$BIN run $S -q -o "$tmp/ref.h5" $L
compare_all() { $PY - "$tmp/ref.h5" "$1" <<'PY'
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1]), h5py.File(sys.argv[2])
names = []
a.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
timing = {"meta/wall_time_s", "meta/start_time", "meta/phase_time", "meta/threads"}
def raw(x):
    x = np.asarray(x)
    return x.tobytes() if x.dtype.kind in "fiu" else x.tolist()
bad = [n for n in names if n not in timing and raw(a[n][()]) != raw(b[n][()])]
assert len(names) > 100, len(names)
assert not bad, f"datasets differ: {bad}"
assert b["meta/completed"][()] == 1
PY
}
$BIN run $S -q -o "$tmp/r1.h5" $L --checkpoint-every 0.2 & pid=$!
wait_checkpoint "$tmp/r1.h5" $pid; signal_running TERM $pid; wait $pid; rc=$?
if [ $rc -eq 3 ] && [ -f "$tmp/r1.h5.ckpt" ] && [ -f "$tmp/r1.h5.partial" ] && $BIN run --resume "$tmp/r1.h5" -q &&
   [ -f "$tmp/r1.h5" ] && [ ! -e "$tmp/r1.h5.ckpt" ] && [ ! -e "$tmp/r1.h5.partial" ] && compare_all "$tmp/r1.h5"
then ok resume_after_sigterm_bit_identical; else ko resume_after_sigterm_bit_identical "rc=$rc"; fi
$BIN run $S -q -o "$tmp/r2.h5" $L --checkpoint-every 0.2 & pid=$!
wait_checkpoint "$tmp/r2.h5" $pid; sleep 0.1; signal_running KILL $pid; wait $pid 2>/dev/null
if [ -f "$tmp/r2.h5.ckpt" ] && $BIN run --resume "$tmp/r2.h5" -q && compare_all "$tmp/r2.h5"
then ok resume_after_sigkill_bit_identical; else ko resume_after_sigkill_bit_identical "see above"; fi
msg=$($BIN run --resume "$tmp/r2.h5" -q 2>&1); rc=$?
if [ $rc -eq 2 ] && echo "$msg" | grep -q "is complete"; then ok resume_refuses_complete; else ko resume_refuses_complete "rc=$rc $msg"; fi
msg=$($BIN run --resume "$tmp/nothing.h5" -q 2>&1); rc=$?
if [ $rc -eq 2 ] && echo "$msg" | grep -q "no checkpoint"; then ok resume_without_checkpoint; else ko resume_without_checkpoint "rc=$rc $msg"; fi

# Numerical faults: a model that returns NaN stops the run with an error naming the vehicle, time and model,
# exit status 1, and the partial result is kept and readable.
if cc -std=c11 -O1 -fPIC -shared -Iinclude tests/data/nan_plugin.c -o "$tmp/nan_plugin.so" -lm 2>"$tmp/cc.log"; then
  printf 'road: {length_m: 1000}\ntime: {duration_s: 60, dt_s: 0.1}\nfleet:\n  vehicles: 10\n  classes: [{class: midsize_sedan, count: 10}]\n  drivers: [{model: plugin, path: nan_plugin.so, count: 10}]\ninitial: {state: rest}\n' > "$tmp/nan.yaml"
  msg=$($BIN run "$tmp/nan.yaml" -q -o "$tmp/nan.h5" 2>&1); rc=$?
  if [ $rc -eq 1 ] && echo "$msg" | grep -q "numerical fault at t = .*vehicle [0-9]* (driver group .*model nan_after_5mps" &&
     [ -f "$tmp/nan.h5.partial" ] && [ ! -e "$tmp/nan.h5" ] &&
     $PY -c "import h5py,sys; f=h5py.File(sys.argv[1]); assert f['meta/completed'][()]==0; assert 'numerical fault' in f['meta/reason'][()].decode()" "$tmp/nan.h5.partial"
  then ok numerical_fault_stops_run; else ko numerical_fault_stops_run "rc=$rc $msg"; fi
else
  ko numerical_fault_stops_run "cannot build the test plugin: $(cat "$tmp/cc.log")"
fi

# Disk full (a file-size limit, without ignoring SIGXFSZ: wavefuel does): refused before simulating, with the size
# it needs, exit status 1, nothing left. tests/t_disk_full.sh covers failures at every point of a run.
# WF_TEST_MIN_FSIZE_KB (set by tools/tsan-tests.sh): limits below it crash the runtime, not wavefuel.
if [ 200 -lt "${WF_TEST_MIN_FSIZE_KB:-0}" ]; then
  echo "# SKIP disk_full_clear_error: a 200 kB limit is below WF_TEST_MIN_FSIZE_KB"
else
msg=$( (ulimit -f 200; $BIN run $S -q -o "$tmp/full.h5" --set fleet.vehicles=500 --set road.length_m=10000 \
        --set time.duration_s=200 --set output.trajectory_interval_s=0.1) 2>&1); rc=$?
if [ $rc -eq 1 ] && echo "$msg" | grep -q "full.h5.partial: cannot create the result file, which needs up to about 32.* MB" &&
   echo "$msg" | grep -q "file size limit (ulimit -f) is 205 kB" && [ ! -e "$tmp/full.h5" ] && [ ! -e "$tmp/full.h5.partial" ]
then ok disk_full_clear_error; else ko disk_full_clear_error "rc=$rc $msg"; fi
fi
