#!/usr/bin/env bash
# Event counters against counts made by hand (docs/metrics.md): one vehicle plays a scripted acceleration sequence
# (examples/plugins/scripted_accel.c) on a ring and on an empty corridor, and its stops, hard-braking events and
# stopped time must be exactly the numbers worked out below. dt = 0.25 s and accelerations that are multiples of
# 0.25 m/s^2 keep every speed exact in binary, so every threshold comparison is decided without rounding.
# Thresholds: v_stop = 0.5 m/s, v_go = 2 m/s, hard braking a < -1 m/s^2 (strict).
#
# The trace (segment: a x steps: speeds at the steps' starts -> speed after):
#   1: +1   x4  0 .25 .5 .75       -> 1       never above v_go: not moving
#   2: -1   x3  1 .75 .5           -> .25     below v_stop, but no stop (v_go never exceeded); a = -1 is not hard
#   3: +1   x3  .25 .5 .75         -> 1
#   4: -2   x2  1 .5               -> 0       hard episode 1 (2 steps); still no stop
#   5: +2   x6  0 .5 1 1.5 2 2.5   -> 3       moving from the end of the 5th step (2.5 > v_go)
#   6: -1.5 x4  3 2.625 2.25 1.875 -> 1.5     hard episode 2 (4 steps)
#   7: -0.5 x1  1.5                -> 1.375   ends episode 2
#   8: -1.5 x3  1.375 1 .625       -> .25     hard episode 3; stop 1 at the end of its last step (step 25)
#   9: -1   x2  .25 0              -> 0       the second step asks to brake at rest: v stays 0; not hard
#  10: +1   x2  0 .25              -> .5      not below v_stop, not above v_go
#  11: -1   x1  .5                 -> .25     a dip below v_stop while not moving: no stop
#  12: +3   x3  .25 1 1.75         -> 2.5     moving again; then a = 0 and v = 2.5 to the end (40 steps)
# Whole run: stops 1 (hysteresis ignored: 3), hard brakes 3 (counted every step: 9), steps starting below v_stop
# 2+1+1+2+2+1 = 9, time stopped 2.25 s.
# Window after a 5 s warm-up (steps 20..39): episode 2 began at step 18, in the warm-up, so its steps 20-21 are no
# onset: hard brakes 1; stops 1; steps below v_stop 26, 27, 28, 29, 31: 1.25 s.
# The corridor's vehicle enters at t = 1 s (arrival 0 at demand 3600 veh/h), so with a 5 s warm-up its window starts
# at its 16th step: trip counts as the whole run; window (/summary) hard brakes 2 (episodes 2 and 3), stops 1,
# stopped 1.25 s of 10 s on the road.
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
BUILD=${BUILD:-build}
PY=/usr/bin/python3
SO="$(pwd)/$BUILD/plugins/scripted_accel.so"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
if [ ! -f "$SO" ]; then echo "FAIL event_counters_plugin: $SO missing: run make tests"; exit 1; fi

SCRIPT="{a1_mps2: 1, n1_steps: 4, a2_mps2: -1, n2_steps: 3, a3_mps2: 1, n3_steps: 3, a4_mps2: -2, n4_steps: 2,
         a5_mps2: 2, n5_steps: 6, a6_mps2: -1.5, n6_steps: 4, a7_mps2: -0.5, n7_steps: 1, a8_mps2: -1.5, n8_steps: 3,
         a9_mps2: -1, n9_steps: 2, a10_mps2: 1, n10_steps: 2, a11_mps2: -1, n11_steps: 1, a12_mps2: 3, n12_steps: 3}"
cat >"$tmp/ring.yaml" <<EOF
name: scripted_ring
road: {length_m: 1000}
time: {duration_s: 10, dt_s: 0.25, output_interval_s: 0.25}
fleet:
  vehicles: 1
  classes: [{class: midsize_sedan, fraction: 1.0}]
  drivers: [{model: plugin, path: $SO, fraction: 1.0, params: $SCRIPT}]
initial: {state: rest}
statistics: {v_stop_mps: 0.5, v_go_mps: 2.0, hard_brake_mps2: 1.0}
EOF
cat >"$tmp/corridor.yaml" <<EOF
name: scripted_corridor
road: {type: corridor, length_m: 1000}
time: {duration_s: 15, dt_s: 0.25, output_interval_s: 0.25}
fleet:
  classes: [{class: midsize_sedan, fraction: 1.0}]
  drivers: [{model: plugin, path: $SO, fraction: 1.0, params: $SCRIPT}]
corridor:
  inflow: {flow_vph: 3600, vehicles: 1, entry_speed_mps: 0}
statistics: {v_stop_mps: 0.5, v_go_mps: 2.0, hard_brake_mps2: 1.0}
EOF

# check NAME FILE GROUP STOPS HARD STOPPED_S: the vehicle's counters in /vehicles (ring) or /trips (corridor).
check() {
  local name=$1 file=$2 group=$3 stops=$4 hard=$5 stopped=$6
  if $PY - "$file" "$group" "$stops" "$hard" "$stopped" <<'PY'; then echo "PASS $name"; else echo "FAIL $name"; fi
import sys, h5py
f, g = h5py.File(sys.argv[1]), sys.argv[2]
want = {"stops": int(sys.argv[3]), "hard_brakes": int(sys.argv[4]), "time_stopped": float(sys.argv[5])}
got = {k: f[g + "/" + k][()] for k in want}
assert all(len(v) == 1 for v in got.values()), got
got = {k: v[0] for k, v in got.items()}
bad = {k: (got[k], want[k]) for k in want if got[k] != want[k]}
if g == "trips":
    assert f["trips/completed"][0] == 0 and f["trips/entry_speed"][0] == 0.0
if bad:
    print("  got, want:", bad)
    sys.exit(1)
PY
}

run() { "$BIN" run "$@" -q --force 2>&1; }
# The ring with the fused step (no trajectories) and with the multi-pass step (a trajectory frame every step).
if run "$tmp/ring.yaml" -o "$tmp/ring.h5" && run "$tmp/ring.yaml" -o "$tmp/ring_traj.h5" \
    --set output.trajectories=true --set output.trajectory_interval_s=0.25 &&
  run "$tmp/ring.yaml" -o "$tmp/ring_warm.h5" --set time.warmup_s=5; then
  check events_ring_fused "$tmp/ring.h5" vehicles 1 3 2.25
  check events_ring_multipass "$tmp/ring_traj.h5" vehicles 1 3 2.25
  check events_ring_warmup "$tmp/ring_warm.h5" vehicles 1 1 1.25
else
  echo "FAIL events_ring_runs"
fi
# The corridor: the trip covers the whole run (warm-up included), the vehicle stays on the road.
if run "$tmp/corridor.yaml" -o "$tmp/corridor.h5" && run "$tmp/corridor.yaml" -o "$tmp/corridor_warm.h5" \
    --set time.warmup_s=5; then
  check events_corridor_trip "$tmp/corridor.h5" trips 1 3 2.25
  check events_corridor_trip_warmup "$tmp/corridor_warm.h5" trips 1 3 2.25
  if $PY - "$tmp/corridor_warm.h5" <<'PY'; then echo "PASS events_corridor_window"; else echo "FAIL events_corridor_window"; fi
import h5py, sys
s = h5py.File(sys.argv[1])["summary"]
vkt, vh = s["vkt"][()], s["vht"][()]
got = (s["hard_brakes_per_vkm"][()] * vkt, s["stops_per_vkm"][()] * vkt, s["time_stopped_share"][()] * vh * 3600)
ok = abs(vh * 3600 - 10) < 1e-9 and all(abs(g - w) < 1e-9 for g, w in zip(got, (2, 1, 1.25)))
print("  hard, stops, stopped_s, vehicle-time:", got, vh * 3600)
sys.exit(0 if ok else 1)
PY
else
  echo "FAIL events_corridor_runs"
fi
