#!/usr/bin/env bash
# `wavefuel sweep` end to end: the table is identical (every value of /params, /runs, /metrics, /class_metrics) run
# serially, on 2 threads and under `mpirun -n 2`; each row equals the `wavefuel run` of the command the sweep
# prints (and its per-run file); a failed run is recorded while the others complete; resuming skips the finished
# rows (a complete table, an extended sweep, a sweep interrupted by SIGINT); bad input is refused.
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
PY=/usr/bin/python3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

TINY=$PWD/tests/data/tiny_ring.yaml
# 2 noise levels x 2 fleet sizes x 2 seeds = 8 runs of a 22-vehicle ring, a few ms each.
sweep() { # sweep FILE VEHICLES SEEDS [DURATION]
  cat >"$1" <<EOF
scenario: $TINY
set: {time.duration_s: ${4:-20}, output.trajectories: false}
axes:
  - key: fleet.drivers[0].noise_mps2
    values: [0.1, 0.4]
  - key: fleet.vehicles
    values: $2
seeds: $3
EOF
}
sweep "$tmp/s1.yaml" "[18, 22]" 2

# Compares the reproducible groups of two tables; extra args name datasets to skip.
cat >"$tmp/same.py" <<'PY'
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
skip = set(sys.argv[3:])
for g in ("params", "runs", "metrics", "class_metrics"):
    assert set(a[g]) == set(b[g]), f"{g}: datasets {sorted(a[g])} vs {sorted(b[g])}"
    for n in a[g]:
        if f"{g}/{n}" in skip:
            continue
        x, y = a[g][n][()], b[g][n][()]
        assert x.shape == y.shape, f"{g}/{n}: shape {x.shape} vs {y.shape}"
        if x.dtype.kind == "f":
            assert np.array_equal(x.view(np.uint64), y.view(np.uint64)), f"{g}/{n} differs"
        else:
            assert (x == y).all(), f"{g}/{n} differs"
assert a["metrics/fuel"].shape[0] > 0
PY
same() { $PY "$tmp/same.py" "$@"; }

$BIN sweep "$tmp/s1.yaml" -o "$tmp/t1.h5" --threads 1 -q; rc1=$?
$BIN sweep "$tmp/s1.yaml" -o "$tmp/t2.h5" --threads 2 -q; rc2=$?
if [ $rc1 -eq 0 ] && [ $rc2 -eq 0 ] && same "$tmp/t1.h5" "$tmp/t2.h5" &&
   $PY -c "import h5py,sys; f=h5py.File(sys.argv[1]); g=h5py.File(sys.argv[2]); \
assert f['timing/workers'][()]==1 and g['timing/workers'][()]==2; assert (f['runs/status'][()]==b'ok').all(); \
assert len(set(f['metrics/fuel'][()]))==8" "$tmp/t1.h5" "$tmp/t2.h5"; then
  ok table_same_on_1_and_2_threads
else ko table_same_on_1_and_2_threads "rc $rc1 $rc2"; fi

# Each row against the single run of its printed command, run as printed (bitwise), and the printed commands against
# /runs/command: the same but for the first word, the program as invoked here versus the installed name `wavefuel`.
$BIN sweep "$tmp/s1.yaml" --list >"$tmp/cmds.txt"
i=0; run_ok=1
while IFS= read -r cmd; do
  eval "$cmd" -o "$tmp/r$i.h5" -q || run_ok=0
  i=$((i + 1))
done <"$tmp/cmds.txt"
if [ $run_ok -eq 1 ] && [ $i -eq 8 ] && $PY - "$tmp/t1.h5" "$tmp/cmds.txt" "$tmp" <<'PY'
import sys, h5py, numpy as np
t = h5py.File(sys.argv[1], "r")
cmds = open(sys.argv[2]).read().splitlines()
table = [c.decode() for c in t["runs/command"][()]]
assert all(c.split(" ", 1)[0] == "wavefuel" for c in table), table[0]
assert [c.split(" ", 1)[1] for c in table] == [c.split(" ", 1)[1] for c in cmds], "--list differs from /runs/command"
for i in range(len(cmds)):
    r = h5py.File(f"{sys.argv[3]}/r{i}.h5", "r")
    assert r["meta/overrides"][()] == t["runs/overrides"][i], i
    assert r["meta/seed"][()] == t["runs/seed"][i], i
    for name, d in t["metrics"].items():
        v, w = r["summary/" + name][()], d[i]
        assert np.array_equal(np.float64(v).view(np.uint64), np.float64(w).view(np.uint64)) or v == w, (i, name, v, w)
        assert d.attrs["units"] == r["summary/" + name].attrs["units"], name
    for name, d in t["class_metrics"].items():
        if name == "class_count":
            assert (d[i] == r["classes/count"][()]).all(), i
            continue
        assert np.array_equal(d[i].view(np.uint64), r["summary/" + name][()].view(np.uint64)), (i, name)
PY
then ok rows_equal_single_runs; else ko rows_equal_single_runs "see above"; fi

# Per-run files: named in the table, each the full result of its run; the rest of the table unchanged.
$BIN sweep "$tmp/s1.yaml" -o "$tmp/t3.h5" --threads 2 --per-run-files "$tmp/runs" -q
if same "$tmp/t1.h5" "$tmp/t3.h5" runs/file && $PY - "$tmp/t3.h5" <<'PY'
import sys, os, h5py
t = h5py.File(sys.argv[1], "r")
files = [f.decode() for f in t["runs/file"][()]]
assert len(set(files)) == 8 and all(os.path.exists(f) for f in files), files
for i, f in enumerate(files):
    r = h5py.File(f, "r")
    assert r["summary/fuel"][()] == t["metrics/fuel"][i] and r["meta/overrides"][()] == t["runs/overrides"][i]
    assert r["meta/completed"][()] == 1 and r["timeseries/t"].shape[0] == 21
PY
then ok per_run_files; else ko per_run_files "see above"; fi

# MPI: the same table from two ranks (rank 0 hands out runs, both compute).
# Bounded by a timeout: a hung MPI job must fail this test, not hang the whole suite.
if command -v mpicc >/dev/null 2>&1 && command -v mpirun >/dev/null 2>&1; then
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
  # The default build tree: a sanitizer run of the suite (BUILD=build-san in the environment) must not mix its objects.
  if make -s --no-print-directory mpi BUILD=build >"$tmp/make_mpi.log" 2>&1; then
    timeout 300 mpirun -n 2 --oversubscribe bin/wavefuel-mpi "$tmp/s1.yaml" -o "$tmp/tm.h5" -q >"$tmp/mpi.log" 2>&1; rc=$?
    if [ $rc -eq 0 ] && same "$tmp/t1.h5" "$tmp/tm.h5" &&
       $PY -c "import h5py,sys; f=h5py.File(sys.argv[1]); assert f['timing/mode'][()]==b'mpi' and f['timing/workers'][()]==2" "$tmp/tm.h5"; then
      ok table_same_under_mpirun_n2
    else ko table_same_under_mpirun_n2 "rc $rc: $(tail -5 "$tmp/mpi.log")"; fi
  else ko table_same_under_mpirun_n2 "make mpi failed: $(tail -3 "$tmp/make_mpi.log")"; fi
else
  echo "NOTE t_sweep: mpicc/mpirun not installed, MPI comparison skipped (tools/install-deps.sh mpi)"
fi

# A failing run (0 vehicles: out of range) is recorded with its error; the others complete; exit status 1.
sweep "$tmp/s2.yaml" "[22, 0]" 2
$BIN sweep "$tmp/s2.yaml" -o "$tmp/f.h5" --threads 2 2>"$tmp/f.err" >/dev/null; rc=$?
if [ $rc -eq 1 ] && grep -q "run 2 failed: .*fleet.vehicles" "$tmp/f.err" && grep -q "reproduce: $(dirname "$BIN")/wavefuel run" "$tmp/f.err" &&
   $PY - "$tmp/f.h5" <<'PY'
import sys, h5py, numpy as np
t = h5py.File(sys.argv[1], "r")
st = [s.decode() for s in t["runs/status"][()]]
veh = t["params/vehicles"][()]
assert st == ["ok" if v == 22 else "failed" for v in veh], st
err = [e.decode() for e in t["runs/error"][()]]
assert all(("fleet.vehicles" in e) == (v == 0) for e, v in zip(err, veh)), err
assert np.isnan(t["metrics/fuel"][()][veh == 0]).all() and (t["metrics/fuel"][()][veh == 22] > 0).all()
assert t["meta/runs_failed"][()] == 4 and t["meta/runs_ok"][()] == 4 and t["meta/complete"][()] == 1
PY
then ok failed_run_recorded; else ko failed_run_recorded "rc $rc: $(head -3 "$tmp/f.err")"; fi

# A corridor base scenario: every run is recorded as failed with the reason (the table holds ring metrics).
cat >"$tmp/cor.yaml" <<EOF
scenario: $PWD/tests/data/corridor_resume.yaml
set: {time.duration_s: 60, time.warmup_s: 0}
seeds: 2
EOF
$BIN sweep "$tmp/cor.yaml" -o "$tmp/cor.h5" 2>"$tmp/cor.err" >/dev/null; rc=$?
if [ $rc -eq 1 ] && grep -q "road.type corridor: sweeps tabulate ring metrics" "$tmp/cor.err" &&
   $PY -c "import h5py,sys; t=h5py.File(sys.argv[1]); assert [s.decode() for s in t['runs/status'][()]] == ['failed'] * 2" "$tmp/cor.h5"
then ok corridor_sweep_refused; else ko corridor_sweep_refused "rc $rc: $(head -3 "$tmp/cor.err")"; fi

# Rerun of a finished table: nothing runs, the file is untouched; --retry-failed runs the failed rows only.
sum1=$(md5sum <"$tmp/f.h5")
out=$($BIN sweep "$tmp/s2.yaml" -o "$tmp/f.h5" 2>&1); rc=$?
if [ $rc -eq 1 ] && echo "$out" | grep -q "all 8 runs already done" && [ "$sum1" = "$(md5sum <"$tmp/f.h5")" ]; then
  ok rerun_skips_finished
else ko rerun_skips_finished "rc $rc: $out"; fi
out=$($BIN sweep "$tmp/s2.yaml" -o "$tmp/f.h5" --retry-failed 2>&1); rc=$?
if [ $rc -eq 1 ] && echo "$out" | grep -q "4 runs to do"; then ok retry_failed; else ko retry_failed "rc $rc: $out"; fi

# An extended sweep (seed 1, then seeds 1 and 2) runs only the new rows and ends equal to the whole sweep run once.
sweep "$tmp/s3.yaml" "[18, 22]" "[1]"
$BIN sweep "$tmp/s3.yaml" -o "$tmp/e.h5" -q
sweep "$tmp/s3.yaml" "[18, 22]" "[1, 2]"
out=$($BIN sweep "$tmp/s3.yaml" -o "$tmp/e.h5" 2>&1); rc=$?
if [ $rc -eq 0 ] && echo "$out" | grep -q "4 of 8 runs already done" && echo "$out" | grep -q "4 runs to do" &&
   same "$tmp/t1.h5" "$tmp/e.h5"; then
  ok extended_sweep_resumes
else ko extended_sweep_resumes "rc $rc: $out"; fi

# SIGINT after the first run: exit 3, the table holds the finished rows; the rerun does only the others and the
# result equals an uninterrupted sweep.
sweep "$tmp/s4.yaml" "[22]" 3 8000   # 2 x 1 x 3 = 6 runs of about 0.2 s each
$BIN sweep "$tmp/s4.yaml" -o "$tmp/i.h5" --threads 1 2>"$tmp/i.err" >/dev/null &
pid=$!
for _ in $(seq 400); do grep -q '^\[1/6\]' "$tmp/i.err" && break; sleep 0.05; done
kill -INT $pid; wait $pid; rc=$?
partial=$($PY -c "import h5py,sys; f=h5py.File(sys.argv[1]); print(f['meta/runs_ok'][()], f['meta/runs_pending'][()])" "$tmp/i.h5" 2>&1)
out=$($BIN sweep "$tmp/s4.yaml" -o "$tmp/i.h5" --threads 1 2>&1); rc2=$?
$BIN sweep "$tmp/s4.yaml" -o "$tmp/full.h5" --threads 2 -q
done_before=${partial% *}
if [ $rc -eq 3 ] && [ "${partial#* }" -gt 0 ] && [ "$done_before" -ge 1 ] && [ $rc2 -eq 0 ] &&
   echo "$out" | grep -q "resuming .*: $done_before of 6 runs already done" && same "$tmp/full.h5" "$tmp/i.h5"; then
  ok interrupted_sweep_resumes
else ko interrupted_sweep_resumes "rc $rc, ok/pending '$partial', rerun rc $rc2: $out"; fi

# Bad input: exit 2, a message with file:line, and no table; a table path holding something else is refused.
printf 'scenario: %s\naxes:\n  - key: fleet.vehicles\n    valeus: [1]\n' "$TINY" >"$tmp/bad.yaml"
err=$($BIN sweep "$tmp/bad.yaml" -o "$tmp/bad.h5" 2>&1); rc=$?
if [ $rc -eq 2 ] && echo "$err" | grep -q "bad.yaml:4: unknown key 'axes\[0\].valeus' (did you mean 'values'?)" &&
   [ ! -e "$tmp/bad.h5" ]; then ok bad_sweep_file; else ko bad_sweep_file "rc $rc: $err"; fi
sum1=$(md5sum <"$tmp/r0.h5")
err=$($BIN sweep "$tmp/s1.yaml" -o "$tmp/r0.h5" 2>&1); rc=$?
if [ $rc -eq 2 ] && echo "$err" | grep -q "not a wavefuel sweep table" && [ "$sum1" = "$(md5sum <"$tmp/r0.h5")" ]; then
  ok refuses_foreign_file
else ko refuses_foreign_file "rc $rc: $err"; fi
touch "$tmp/t1.h5.partial"
err=$($BIN sweep "$tmp/s1.yaml" -o "$tmp/t1.h5" 2>&1); rc=$?
if [ $rc -eq 2 ] && echo "$err" | grep -q "t1.h5.partial exists" &&
   $BIN sweep "$tmp/s1.yaml" -o "$tmp/t1.h5" --force -q && [ ! -e "$tmp/t1.h5.partial" ]; then
  ok partial_guard_and_force
else ko partial_guard_and_force "rc $rc: $err"; fi
