#!/usr/bin/env bash
# Checkpoint and exact restart of corridor runs (docs/output.md, docs/corridors.md): a run interrupted by SIGTERM
# (twice, the second time while resumed) or killed by SIGKILL after a checkpoint, then resumed with --resume,
# must give the same bytes as the uninterrupted run in every dataset and every attribute (wall-clock times and the
# thread count excepted), with both fixed-step integrators; checkpoints of ring runs, of other runs, and damaged
# ones must be refused with exit status 2 and a message naming the problem, leaving the partial result untouched.
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
PY=/usr/bin/python3
tmp=$(mktemp -d)
pids=()
trap 'for p in "${pids[@]}"; do kill -KILL "$p" 2>/dev/null; done; rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

S=tests/data/corridor_resume.yaml
# Long enough (about 2 s here) that a signal after the first checkpoint (0.2 s) lands midway.
L="--set time.duration_s=9000 --set seed=23"

# Every object of file 1 and 2: the same groups and datasets, the same attributes, the same bytes (dtype, shape
# and values), except the wall-clock start, wall time and thread count of /meta.
cat > "$tmp/compare.py" <<'PY'
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
timing = {"meta/wall_time_s", "meta/start_time", "meta/threads"}
def objects(f):
    d = {"": f}
    f.visititems(lambda n, o: d.__setitem__(n, o))
    return d
oa, ob = objects(a), objects(b)
assert set(oa) == set(ob), f"objects in one file only: {sorted(set(oa) ^ set(ob))}"
def raw(x):
    x = np.asarray(x)
    return (x.dtype.str, x.shape, x.tobytes()) if x.dtype.kind in "fiub" else (x.shape, x.tolist())
bad = []
n_data = 0
for n, o in oa.items():
    p = ob[n]
    if sorted(o.attrs) != sorted(p.attrs) or any(raw(o.attrs[k]) != raw(p.attrs[k]) for k in o.attrs):
        bad.append(n + " (attributes)")
    if isinstance(o, h5py.Dataset):
        n_data += 1
        if n not in timing and (o.dtype != p.dtype or raw(o[()]) != raw(p[()])):
            bad.append(n)
assert n_data > 100, n_data
assert not bad, f"differ: {bad}"
assert b["meta/completed"][()] == 1 and b["meta/road_type"][()] == b"corridor"
# The run was long enough to matter: trips, queue, overlaps and trajectories all present.
assert b["trips/serial"].shape[0] > 1000 and b["trajectories/x"].shape[0] > 100000, b["trips/serial"].shape
PY
compare() { $PY "$tmp/compare.py" "$1" "$2"; }

. tests/interrupt.sh
# Start a run in the background (pid) and wait until it has written a checkpoint while stepping.
start_until_checkpoint() { # result, extra args...
  local out=$1; shift
  $BIN run $S -q -o "$out" $L "$@" 2>"$out.err" & pid=$!
  pids+=("$pid")
  wait_checkpoint "$out" $pid
}

$BIN run $S -q -o "$tmp/ref.h5" $L || ko reference_run "rc=$?"
$BIN run $S -q -o "$tmp/ref_euler.h5" $L --set time.integrator=euler || ko reference_run_euler "rc=$?"

# SIGTERM: the run stops after a step, keeps its partial result and checkpoint (exit 3); resumed with one thread,
# interrupted again, resumed again, it completes with the uninterrupted run's bytes and removes the checkpoint.
start_until_checkpoint "$tmp/t.h5" --checkpoint-every 0.2
signal_running TERM $pid; wait $pid; rc1=$?
# The corridor's row counters, from the writer's table.
grep -qF "/meta/timeseries_rows, trip_rows and trajectory_rows count the rows written" "$tmp/t.h5.err" ||
  ko corridor_partial_message "$(cat "$tmp/t.h5.err")"
ino=$(ckpt_inode "$tmp/t.h5")
$BIN run --resume "$tmp/t.h5" -q --threads 1 --checkpoint-every 0.1 & pid=$!
pids+=("$pid")
wait_checkpoint "$tmp/t.h5" $pid "$ino"; signal_running TERM $pid; wait $pid; rc2=$?
if [ $rc1 -eq 3 ] && [ $rc2 -eq 3 ] && [ -f "$tmp/t.h5.ckpt" ] && [ -f "$tmp/t.h5.partial" ] &&
   $BIN run --resume "$tmp/t.h5" -q && [ -f "$tmp/t.h5" ] && [ ! -e "$tmp/t.h5.ckpt" ] &&
   [ ! -e "$tmp/t.h5.partial" ] && compare "$tmp/ref.h5" "$tmp/t.h5"
then ok corridor_resume_after_sigterm_twice_bit_identical
else ko corridor_resume_after_sigterm_twice_bit_identical "rc=$rc1,$rc2"; fi

# SIGKILL after a checkpoint (euler): nothing is written at the end; the resumed run truncates the partial result to
# the checkpoint's rows and completes with the uninterrupted run's bytes.
start_until_checkpoint "$tmp/k.h5" --set time.integrator=euler --checkpoint-every 0.2
sleep 0.1; signal_running KILL $pid; wait $pid 2>/dev/null  # a little past the checkpoint
if [ -f "$tmp/k.h5.ckpt" ] && [ -f "$tmp/k.h5.partial" ] && $BIN run --resume "$tmp/k.h5" -q &&
   compare "$tmp/ref_euler.h5" "$tmp/k.h5"
then ok corridor_resume_after_sigkill_bit_identical; else ko corridor_resume_after_sigkill_bit_identical "see above"; fi

# Warm-up 0: every vehicle enters with the statistics window open, so from the first step the kernel keeps only
# the trip totals and the window totals are read from them (src/core/corridor.c, window_is_trip); interrupted and
# resumed that way, the run must still give the uninterrupted bytes. (The window totals a checkpoint holds are
# checked vehicle by vehicle in tests/test_corridor.c, test_window_totals.)
W="--set time.warmup_s=0"
$BIN run $S -q -o "$tmp/ref_open.h5" $L $W || ko reference_run_open "rc=$?"
start_until_checkpoint "$tmp/w0.h5" $W --checkpoint-every 0.2
signal_running TERM $pid; wait $pid; rc1=$?
if [ $rc1 -eq 3 ] && $BIN run --resume "$tmp/w0.h5" -q && compare "$tmp/ref_open.h5" "$tmp/w0.h5"
then ok corridor_resume_window_from_start_bit_identical
else ko corridor_resume_window_from_start_bit_identical "rc=$rc1"; fi

msg=$($BIN run --resume "$tmp/k.h5" -q 2>&1); rc=$?
if [ $rc -eq 2 ] && echo "$msg" | grep -q "is complete"; then ok corridor_resume_refuses_complete
else ko corridor_resume_refuses_complete "rc=$rc $msg"; fi

# Refused checkpoints: each resume must fail with status 2 and the expected message, and leave the partial
# result and the checkpoint as they were.
start_until_checkpoint "$tmp/c.h5" --checkpoint-every 0.2
signal_running TERM $pid; wait $pid
$BIN run tests/data/tiny_ring.yaml -q -o "$tmp/ring.h5" --set time.duration_s=200000 --set fleet.vehicles=2000 \
  --set road.length_m=40000 --checkpoint-every 0.2 & pid=$!
pids+=("$pid")
wait_checkpoint "$tmp/ring.h5" $pid; signal_running TERM $pid; wait $pid
cp "$tmp/c.h5.ckpt" "$tmp/c.ckpt.good"
refused() { # name, expected message, result to resume
  local name=$1 want=$2 res=$3 before after msg rc
  before=$(cat "$res.partial" "$res.ckpt" 2>/dev/null | md5sum)
  msg=$($BIN run --resume "$res" -q 2>&1); rc=$?
  after=$(cat "$res.partial" "$res.ckpt" 2>/dev/null | md5sum)
  if [ $rc -eq 2 ] && echo "$msg" | grep -qF -- "$want" && [ "$before" = "$after" ] && [ ! -e "$res" ]; then ok "$name"
  else ko "$name" "rc=$rc msg=$msg"; fi
}
if [ -f "$tmp/ring.h5.ckpt" ] && [ -f "$tmp/c.h5.ckpt" ]; then
  # A ring run's checkpoint next to a corridor run's partial result, and the other way round.
  cp "$tmp/ring.h5.ckpt" "$tmp/c.h5.ckpt"
  refused corridor_refuses_ring_checkpoint "is the result of another run than $tmp/c.h5.ckpt" "$tmp/c.h5"
  cp "$tmp/ring.h5.ckpt" "$tmp/ring.ckpt.good"
  cp "$tmp/c.ckpt.good" "$tmp/ring.h5.ckpt"
  refused ring_refuses_corridor_checkpoint "is the result of another run than $tmp/ring.h5.ckpt" "$tmp/ring.h5"
  cp "$tmp/ring.ckpt.good" "$tmp/ring.h5.ckpt"
  # A corridor checkpoint whose kind says ring.
  cp "$tmp/c.ckpt.good" "$tmp/c.h5.ckpt"
  $PY -c "import h5py,sys; f=h5py.File(sys.argv[1],'r+'); f.attrs.modify('kind', b'ring')" "$tmp/c.h5.ckpt"
  refused corridor_refuses_kind_ring "a checkpoint of a ring run, but the scenario it holds is a corridor" "$tmp/c.h5"
  # One flipped bit in the vehicles' positions.
  cp "$tmp/c.ckpt.good" "$tmp/c.h5.ckpt"
  $PY - "$tmp/c.h5.ckpt" <<'PY'
import sys, h5py
f = h5py.File(sys.argv[1], "r+")
d = f["state/x"]
b = d[()]
b[8] ^= 1
d[...] = b
PY
  refused corridor_refuses_damaged_state "does not match the contents" "$tmp/c.h5"
  # A state block missing, one of another size.
  cp "$tmp/c.ckpt.good" "$tmp/c.h5.ckpt"
  $PY -c "import h5py,sys; f=h5py.File(sys.argv[1],'r+'); del f['state/queue_t']" "$tmp/c.h5.ckpt"
  refused corridor_refuses_missing_block "state blocks where this run has" "$tmp/c.h5"
  cp "$tmp/c.ckpt.good" "$tmp/c.h5.ckpt"
  $PY -c "import h5py,sys,numpy as np; f=h5py.File(sys.argv[1],'r+'); del f['state/mode']
f['state/mode']=np.zeros(7,'u1')" "$tmp/c.h5.ckpt"
  refused corridor_refuses_block_size "state block 'mode' is missing or has 7 bytes" "$tmp/c.h5"
  # A truncated file, and garbage.
  head -c 3000 "$tmp/c.ckpt.good" > "$tmp/c.h5.ckpt"
  refused corridor_refuses_truncated "not a readable checkpoint" "$tmp/c.h5"
  head -c 5000 /dev/urandom > "$tmp/c.h5.ckpt"
  refused corridor_refuses_garbage "not a readable checkpoint" "$tmp/c.h5"
  # The checkpoint of another corridor run (another seed) next to this run's partial result.
  start_until_checkpoint "$tmp/o.h5" --set seed=24 --checkpoint-every 0.2
  signal_running TERM $pid; wait $pid
  cp "$tmp/o.h5.ckpt" "$tmp/c.h5.ckpt"
  refused corridor_refuses_other_run "is the result of another run than $tmp/c.h5.ckpt" "$tmp/c.h5"
  # With its own checkpoint back, the run resumes and completes as the uninterrupted one.
  cp "$tmp/c.ckpt.good" "$tmp/c.h5.ckpt"
  if $BIN run --resume "$tmp/c.h5" -q && compare "$tmp/ref.h5" "$tmp/c.h5"
  then ok corridor_resume_after_refusals; else ko corridor_resume_after_refusals "see above"; fi
else
  ko refused_checkpoints "no checkpoint to work with (ring: $(ls "$tmp" | tr '\n' ' '))"
fi
