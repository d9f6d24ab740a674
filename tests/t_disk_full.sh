#!/usr/bin/env bash
# Write errors at every point of a run (docs/output.md, "Write errors"): for a ring and a corridor, a file size
# limit (ulimit -f) at fractions of the size of a complete result, errors injected into the writes (EIO, a full
# disk or a quota when a chunk is added), a resumed run that fails and is resumed again, a really full tmpfs,
# SIGKILL, and an unwritable directory. Each must
# give a non-zero exit status, a message that names the file and what failed, no FILE.h5, and either no file (the
# failure came before simulating, and the message says so) or a FILE.h5.partial that h5py reads entirely, with
# /meta/completed = 0, the reason, and row counts that match the data.
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
# Under make sanitize the error-injecting library is preloaded ahead of ASan's runtime, which ASan refuses unless
# told not to check the order (its interceptors still wrap the calls the library passes on).
export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}verify_asan_link_order=0"
PY=/usr/bin/python3
tmp=$(mktemp -d)
trap 'chmod -R u+w "$tmp" 2>/dev/null; rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

RING="tests/data/tiny_ring.yaml --set fleet.vehicles=300 --set road.length_m=6000 --set time.duration_s=100 --set output.trajectory_interval_s=0.1"
CORR="tests/data/tiny_corridor.yaml --set corridor.inflow.flow_vph=2500 --set time.duration_s=400 --set output.trajectory_interval_s=0.2"

cat > "$tmp/check.py" <<'PY'
# check.py FILE KIND MODE: the partial result reads entirely and says it is incomplete; prints the phase of the failure.
import sys, h5py, numpy as np
path, kind, mode = sys.argv[1:4]
f = h5py.File(path, "r")
names = []
f.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
for n in names:
    f[n][()]  # every dataset readable: the structure is intact
assert len(names) > 60, f"only {len(names)} datasets"
assert f["meta/completed"][()] == 0, "marked completed"
reason = f["meta/reason"][()].decode()
if mode == "reason":
    assert reason not in ("", "running"), f"reason {reason!r}"
def rows(key, group, first, others):
    n = int(f["meta/" + key][()])
    t = f[group + "/" + first][:]
    assert 0 <= n <= len(t), f"{key} = {n}, {group}/{first} has {len(t)} rows"
    for name in [first] + others:
        d = f[group + "/" + name][:n]
        assert np.isfinite(d).all(), f"{group}/{name}: NaN among the {n} rows counted"
    if first == "t":
        assert (np.diff(t[:n]) >= 0).all(), f"{group}/t not in order"
    return n, len(t)
# Columns never NaN in a record (a corridor's mean speed is NaN while its road is empty).
always = ["mean_speed", "fuel_rate", "class_fuel_rate"] if kind == "ring" else ["vehicles", "entered", "fuel_rate"]
n_ts, len_ts = rows("timeseries_rows", "timeseries", "t", always)
if "trajectories" in f:
    rows("trajectory_rows", "trajectories", "t", ["x", "v", "a", "fuel_rate"])
if kind == "corridor":
    rows("trip_rows", "trips", "serial", ["fuel", "entry_time"])
print("end" if n_ts == len_ts else "run")
PY

# Runs wavefuel with a limit or an injected fault and checks the outcome. Prints the phase reached on success.
#   expect NAME OUT WANT MODE KIND [ENV=...] -- ARGS...  (with LIMIT set: under ulimit -f LIMIT)
expect() {
  local name=$1 out=$2 want=$3 mode=$4 kind=$5; shift 5
  local envs=()
  while [ "$1" != "--" ]; do envs+=("$1"); shift; done
  shift
  rm -f "$out" "$out.partial"
  local msg rc
  msg=$( (if [ -n "${LIMIT:-}" ]; then ulimit -f "$LIMIT"; fi; env "${envs[@]}" $BIN run "$@" -q -o "$out") 2>&1); rc=$?
  local phase=""
  if [ $rc -eq 0 ]; then ko "$name" "exit status 0: $msg"; return; fi
  if ! echo "$msg" | grep -qF -- "$out.partial"; then ko "$name" "message does not name the file: $msg"; return; fi
  if ! echo "$msg" | grep -qE -- "$want"; then ko "$name" "message does not say '$want': $msg"; return; fi
  if [ -e "$out" ]; then ko "$name" "$out exists"; return; fi
  if [ -e "$out.partial" ]; then
    phase=$($PY "$tmp/check.py" "$out.partial" "$kind" "$mode" 2>&1) || { ko "$name" "partial file: $phase"; return; }
  elif echo "$msg" | grep -q "nothing was simulated and the file is removed"; then
    phase=creation
  else
    ko "$name" "no partial file and the message does not say so: $msg"; return
  fi
  echo "$kind $phase" >> "$tmp/phases"
  ok "$name ($phase: $(echo "$msg" | head -1 | cut -c1-150))"
}

cc -std=c11 -O1 -fPIC -shared tests/data/fail_write.c -o "$tmp/fail_write.so" -ldl 2>"$tmp/cc.log" ||
  { ko build_fail_write "$(cat "$tmp/cc.log")"; exit 0; }
for kind in ring corridor; do
  if [ $kind = ring ]; then ARGS=$RING; else ARGS=$CORR; fi
  # A complete result, the number of writes and reservations it takes (tests/data/fail_write.c), its size.
  ref="$tmp/${kind}_ref.h5"
  if LD_PRELOAD="$tmp/fail_write.so" WF_FAIL_LOG="$tmp/${kind}_count" $BIN run $ARGS -q -o "$ref" && [ -f "$ref" ]; then
    ok "${kind}_reference_run"
  else
    ko "${kind}_reference_run" "failed"; continue
  fi
  size=$(stat -c %s "$ref")
  read -r writes fallocs first < <(sed 's/[a-z]*=//g' "$tmp/${kind}_count")
  echo "# $kind: complete result $size bytes, $writes writes ($first while the file is created), $fallocs reservations"

  # A file size limit at a fraction of the complete result's size.
  for pct in 1 25 50 90 99; do
    limit=$((size * pct / 100 / 1024))
    # WF_TEST_MIN_FSIZE_KB (set by tools/tsan-tests.sh): limits below it crash the runtime, not wavefuel.
    if [ "$limit" -lt "${WF_TEST_MIN_FSIZE_KB:-0}" ]; then
      echo "# SKIP ${kind}_ulimit_${pct}pct: limit $limit kB is below WF_TEST_MIN_FSIZE_KB"; continue
    fi
    LIMIT=$limit expect "${kind}_ulimit_${pct}pct" "$tmp/${kind}_u$pct.h5" "file size limit" reason $kind -- $ARGS
  done
  # Just above it: the checks before simulating and the reservations must not refuse a run that fits.
  if (ulimit -f $((size / 1024 + 4096)); $BIN run $ARGS -q -o "$tmp/${kind}_fits.h5") && [ -f "$tmp/${kind}_fits.h5" ]
  then ok "${kind}_ulimit_just_enough"; else ko "${kind}_ulimit_just_enough" "a run that fits was refused"; fi

  # A device error (EIO) at one write, then writes succeed again: while the file is created, at the first write
  # of the run (inside the first chunk appended), in the middle of the run, at the end (the end-of-run results,
  # the status, the close).
  run_writes=$((writes - first))
  for at in "creation $((first / 2))" "first_append $((first + 1))" "mid_run $((first + run_writes / 2))" \
            "end_results $((writes - 8))" "close $writes"; do
    set -- $at
    expect "${kind}_eio_write_$1" "$tmp/${kind}_e$1.h5" "Input/output error" reason $kind \
      LD_PRELOAD="$tmp/fail_write.so" WF_FAIL_WRITE_AT=$2 WF_FAIL_WRITE_COUNT=1 -- $ARGS
  done
  # Every write fails from the middle of the run on: even the status cannot be written ("running" stays), but
  # the file still reads, with the rows written before.
  expect "${kind}_eio_all_writes_from_mid_run" "$tmp/${kind}_eall.h5" "Input/output error" any $kind \
    LD_PRELOAD="$tmp/fail_write.so" WF_FAIL_WRITE_AT=$((first + run_writes / 2)) -- $ARGS
  # The disk fills before the first chunk of trajectories (or trips) is added, and before the last.
  expect "${kind}_enospc_first_growth" "$tmp/${kind}_g1.h5" "cannot add .* rows to .*No space left on device \(disk full\)" \
    reason $kind LD_PRELOAD="$tmp/fail_write.so" WF_FAIL_FALLOCATE_AT=1 WF_FAIL_ERRNO=ENOSPC -- $ARGS
  expect "${kind}_edquot_last_reservation" "$tmp/${kind}_gl.h5" "Disk quota exceeded" reason $kind \
    LD_PRELOAD="$tmp/fail_write.so" WF_FAIL_FALLOCATE_AT="$fallocs" WF_FAIL_ERRNO=EDQUOT -- $ARGS
done

# Checkpoints and write errors together: a run interrupted (SIGTERM) at its first reservation leaves a checkpoint;
# resumed under a file size limit it fails at a later chunk, keeping a readable partial result; resumed again with
# room it completes with the bytes of the uninterrupted run (the counters, the allocated datasets and the chunks
# written after the checkpoint agree with its cursors).
cat > "$tmp/same.py" <<'PY'
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
timing = {"meta/wall_time_s", "meta/start_time", "meta/threads", "meta/phase_time"}
names = []
a.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
def raw(x):
    x = np.asarray(x)
    return (x.dtype.str, x.shape, x.tobytes()) if x.dtype.kind in "fiub" else (x.shape, x.tolist())
bad = [n for n in names if n not in timing and (n not in b or raw(a[n][()]) != raw(b[n][()]))]
assert not bad, f"datasets differ: {bad}"
assert b["meta/completed"][()] == 1
PY
for kind in ring corridor; do
  if [ $kind = ring ]; then ARGS=$RING; else ARGS=$CORR; fi
  out="$tmp/${kind}_rs.h5" ref="$tmp/${kind}_ref.h5"
  [ -f "$ref" ] || { ko "${kind}_resume_after_write_error" "no reference result"; continue; }
  LD_PRELOAD="$tmp/fail_write.so" WF_STOP_AT_FALLOCATE=1 $BIN run $ARGS -q -o "$out" 2>/dev/null & pid=$!
  for i in $(seq 1 500); do [ "$(ps -o stat= -p $pid | cut -c1)" = T ] && break; sleep 0.02; done
  kill -TERM $pid; kill -CONT $pid; wait $pid; rc1=$?
  size=$(stat -c %s "$ref")
  msg=$( (ulimit -f $((size * 80 / 100 / 1024)); $BIN run --resume "$out" -q) 2>&1); rc2=$?
  if [ $rc1 -eq 3 ] && [ $rc2 -eq 1 ] && echo "$msg" | grep -q "file size limit" &&
     echo "$msg" | grep -q "resume with --resume" && [ -f "$out.ckpt" ] &&
     chk=$($PY "$tmp/check.py" "$out.partial" $kind reason 2>&1) &&
     $BIN run --resume "$out" -q && [ -f "$out" ] && [ ! -e "$out.ckpt" ] && $PY "$tmp/same.py" "$ref" "$out"
  then ok "${kind}_resume_after_write_error"
  else ko "${kind}_resume_after_write_error" "rc=$rc1,$rc2 ${chk:-} $msg"; fi
done

# The failures above happened before simulating, during the run and at its end, for both kinds of road.
for p in "ring creation" "ring run" "ring end" "corridor creation" "corridor run" "corridor end"; do
  if grep -qx "$p" "$tmp/phases" 2>/dev/null; then ok "failure_point_covered: $p"; else ko "failure_point_covered" "no case failed at: $p"; fi
done

# SIGKILL in the middle of a run: nothing is closed, yet the file reads (its structure was complete before the
# first step and only data changed since), marked running, with counts that match the data. The file is read while
# the run writes it (HDF5 locks files open for writing: HDF5_USE_FILE_LOCKING=FALSE) until it holds records.
$BIN run tests/data/tiny_ring.yaml -q -o "$tmp/kill.h5" --set fleet.vehicles=2000 --set road.length_m=40000 \
  --set time.duration_s=200000 --set output.trajectories=false & pid=$!
for i in $(seq 1 600); do
  sleep 0.1
  HDF5_USE_FILE_LOCKING=FALSE $PY -c "import h5py,sys; f=h5py.File(sys.argv[1],'r'); sys.exit(int(f['meta/timeseries_rows'][()] == 0))" \
    "$tmp/kill.h5.partial" 2>/dev/null && break
done
kill -KILL $pid; wait $pid 2>/dev/null
if [ -f "$tmp/kill.h5.partial" ] && out=$($PY "$tmp/check.py" "$tmp/kill.h5.partial" ring any 2>&1) &&
   $PY -c "import h5py,sys; f=h5py.File(sys.argv[1]); assert f['meta/reason'][()]==b'running'; assert f['meta/timeseries_rows'][()]>0" "$tmp/kill.h5.partial"
then ok sigkill_partial_readable; else ko sigkill_partial_readable "${out:-no partial file}"; fi

# An output directory that cannot be written: a clear error before simulating, nothing left. As root (who may
# write anywhere) the run is made as the unprivileged user nobody.
mkdir -p "$tmp/ro" && chmod 0755 "$tmp" && chmod 0555 "$tmp/ro"
as_user=()
if [ "$(id -u)" -eq 0 ]; then as_user=(setpriv --reuid=65534 --regid=65534 --clear-groups); fi
msg=$("${as_user[@]}" $BIN run tests/data/tiny_ring.yaml -q -o "$tmp/ro/x.h5" 2>&1); rc=$?
if [ $rc -eq 1 ] && echo "$msg" | grep -qF "$tmp/ro/x.h5.partial: cannot create (Permission denied)" &&
   [ -z "$(ls -A "$tmp/ro")" ]
then ok permission_denied_clear_error; else ko permission_denied_clear_error "rc=$rc $msg"; fi
chmod 0700 "$tmp"

# A really full file system (a private tmpfs, when the system lets us mount one): too small from the start, then
# filled by another file while the run goes (the run is stopped meanwhile so the filling comes before its next
# growth).
if unshare -m true 2>/dev/null; then
  ring_size=$(stat -c %s "$tmp/ring_ref.h5")
  mkdir -p "$tmp/small"
  msg=$(unshare -m bash -c 'mount -t tmpfs -o size=$1 tmpfs "$2" && $3 run ${@:4} -q -o "$2/t.h5"; echo "rc=$? left=$(ls -A "$2" | wc -l)"' \
        _ $((ring_size / 2)) "$tmp/small" "$BIN" $RING 2>&1)
  if echo "$msg" | grep -q "rc=1 left=0" && echo "$msg" | grep -qF "$tmp/small/t.h5.partial: cannot create the result file" &&
     echo "$msg" | grep -q "free on its file system (disk full); nothing was simulated"
  then ok tmpfs_too_small_refused; else ko tmpfs_too_small_refused "$msg"; fi
  # Filled while the run goes: the run stops itself before its first growth (tests/data/fail_write.c), the tmpfs
  # is filled, the run continues and the kernel refuses the space.
  cat > "$tmp/fill.sh" <<'SH'
set -u
size=$1 dir=$2 bin=$3 py=$4 check=$5 shim=$6; shift 6
mount -t tmpfs -o size=$size tmpfs "$dir" || exit 9
LD_PRELOAD=$shim WF_STOP_AT_FALLOCATE=1 $bin run "$@" -q -o "$dir/f.h5" 2>"$dir.msg" & pid=$!
for i in $(seq 1 500); do [ "$(ps -o stat= -p $pid | cut -c1)" = T ] && break; sleep 0.02; done
dd if=/dev/zero of="$dir/filler" bs=64k 2>/dev/null
kill -CONT $pid
wait $pid; rc=$?
rm -f "$dir/filler"
echo "rc=$rc"
cat "$dir.msg"
[ -e "$dir/f.h5" ] && echo "final file exists"
[ -e "$dir/f.h5.partial" ] && $py "$check" "$dir/f.h5.partial" ring reason 2>&1
SH
  mkdir -p "$tmp/fs"
  msg=$(unshare -m bash "$tmp/fill.sh" $((64 << 20)) "$tmp/fs" "$BIN" "$PY" "$tmp/check.py" "$tmp/fail_write.so" $RING 2>&1)
  if echo "$msg" | grep -q "rc=1" && echo "$msg" | grep -qF "$tmp/fs/f.h5.partial: cannot add" &&
     echo "$msg" | grep -q "No space left on device (disk full)" && ! echo "$msg" | grep -q "final file exists" &&
     echo "$msg" | grep -qx "run"
  then ok tmpfs_filled_during_run; else ko tmpfs_filled_during_run "$msg"; fi
else
  echo "SKIP tmpfs cases: cannot create a mount namespace (unshare -m) here"
fi
