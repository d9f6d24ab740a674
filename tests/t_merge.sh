#!/usr/bin/env bash
# On-ramp merges with cooperation at the lane's end (corridor.on_ramp, MOBIL's mandatory rule within merge_range_m,
# coop_decel_mps2; src/core/lanes.c, src/core/corridor.c, src/models/lc/mobil.c; docs/lanes.md "Lanes that end",
# "Cooperation") through `wavefuel run`, each result checked by tests/merge_check.py against something computed apart
# from it (numpy recomputations from the trajectories, or the same scenario with cooperation off):
# a. stop-and-go waves upstream of the merge at high demand, none at low demand (issue 18). A 5 km corridor, two
#    main lanes under keep-right rules, an on-ramp whose merge lane runs from 3000 to 3300 m; IDM (v0 30 m/s,
#    T 1.2 s, s0 2 m, a 1, b 1.5 m/s^2, delta 4) with noise 0.2 m/s^2, MOBIL's defaults; midsize sedans (4.9 m);
#    Poisson arrivals, seed 3, 1800 s, warm-up 300 s, trajectories every 1 s.
#      high demand: 3400 veh/h on the main lanes + 900 veh/h on the ramp; low demand: 2400 + 300 veh/h.
#    Definitions (merge_check.py): the upstream vehicles are those entered on a main lane after the warm-up, seen
#    on the main lanes at 500 <= x < 3000 m; a stop-go cycle of such a vehicle there is a fall below 0.5 m/s
#    followed by a rise above 2 m/s (statistics.v_stop_mps and v_go_mps's defaults); downstream is x >= 3500 m
#    (200 m past the merge's end) on the main lanes after the warm-up.
#    Asserted: high demand: >= 40 % of the upstream vehicle-time below 5 m/s, >= 30 % of the upstream vehicles
#    through >= 2 stop-go cycles and >= 70 % of those that stop at all (waves, not one standing queue); low demand:
#    no upstream vehicle with a cycle and every upstream speed above 15 m/s; downstream every speed above 15 m/s at
#    both. Measured when written: high: 1287 vehicles, 69 % of the time below 5 m/s, 50 % stop, 42 % with >= 2
#    cycles (84 % of those that stop, 17 cycles each on average: speeds swing 0 <-> 2-3 m/s about every 15 s as the
#    queue grows back from the merge to the entrance), downstream >= 18.2 m/s; low: 1003 vehicles, none with a
#    cycle, upstream >= 22.1 m/s, downstream >= 19.2 m/s.
# b. cooperation off (coop_decel_mps2: 0) at the high demand of a: the ramp jams (its merge lane full, its queue at
#    the entrance long) and the main lanes stay fast; with the default 1.5 m/s^2 the merges more than double and the
#    queue moves onto the main lanes. Measured: 332 / 114 merges (on / off), 368 / 159 ramp vehicles entered,
#    30.3 / 39.4 vehicles in the merge lane on average, 68 / 5 % of the main lanes' upstream time below 5 m/s.
#    Asserted: merges on >= 2 x off, ramp entries on >= 1.5 x off, the merge lane's mean >= 3 vehicles fuller off,
#    upstream <= 20 % slow off and >= 40 % on.
# c. frames written every step (400 s, no noise, no heterogeneity, no speed limit; a group of slow drivers, v0
#    15 m/s, 30 %, with its own coop_decel 3 m/s^2 and merge_range 150 m, keeps lane 1 slow enough to let merging
#    vehicles in: without it the noise-free main lanes stay fast and the ramp jams, with 165 binding yields and 44
#    merges in 600 s):
#    - every vehicle's acceleration at every step equals IDM in its own lane (written in numpy from the parameters
#      of the scenario text) after the group's limits, capped by the cooperation rule recomputed from the frame
#      (askers: merge-lane vehicles within their merge range; each one's follower: the last lane-1 vehicle whose
#      front is behind the asker's; its bound: its IDM behind the asker when >= -its coop_decel; a > cap ?
#      max(cap, -decel_max) : a), to 1e-9 m/s^2 (measured: 0, to the bit). Frame k is the state after step k's lane
#      changes and entries, from which the engine decides; the vehicles that entered at step k are left out of the
#      asking and yielding only (entries come after the cooperation); no vehicle's acceleration is excluded.
#      Measured: 859616 accelerations, 907 yields that bind in 824 steps, 2663 (asker, follower) pairs yielding.
#    - every merge within the merge range is a change MOBIL's mandatory rule allows (safe under b_mandatory 8 m/s^2
#      for the merger and its new follower), and every merge-lane vehicle offered such a gap takes it (93 of 93);
#    - conservation: tests/corridor_lanes_check.py's `physical` method (vehicles on the road those /trips says,
#      changes seen between frames counted in /trips and /lanes, detectors and Edie's distance from the trips) with
#      the ramp's vehicles entering at start_m (`physical` itself takes all to enter at x = 0), and each lane's
#      vehicles at every step = entries - exits + changes in - out, the merge lane's = ramp entries - merges, no
#      change into the merge lane, /lanes/vehicles at every record.
# d. threads and resume with cooperation: a 90 km corridor whose lane 1 takes all the main demand (IDM with
#    T = 0.1 s fills it past 4096 vehicles, the kernel's and the decisions' threshold for threads, after about
#    1190 s) beside a 5 km merge lane (merge_range_m 5000: the whole merge lane asks); noise on. 1 thread and 2
#    threads give the same bytes; interrupted by SIGTERM on 2 threads and resumed on 1, the same bytes. Yields are
#    counted in its frames (every 10 s) as accelerations equal to the cooperation bound recomputed for them
#    (noise cannot land on that value): measured 107, 12 of them in lane 1 while it held more than 4096.
# e. refusals: coop_decel_mps2 -1 and merge_range_m -5 refused with exit status 2, naming the key, no file written.
set -u
cd "$(dirname "$0")/.." || exit 1
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
PY=/usr/bin/python3
CHECK="$PY tests/merge_check.py"
# Threads that sleep while they wait: on a loaded machine spinning threads can take many times longer (results
# do not depend on it).
export OMP_WAIT_POLICY=passive
. tests/scaffold.sh

# ------------------------------------------------------------------ a. waves upstream at high demand only
# merge FILE MAIN_VPH RAMP_VPH [LANE_CHANGE]: check a's corridor; LANE_CHANGE: the group's lane_change entry.
merge() {
  cat >"$1" <<EOF
name: merge
seed: 3
road: {type: corridor, length_m: 5000, lanes: 2, lane_rule: keep_right}
time: {duration_s: 1800, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 300}
fleet:
  classes: [{class: midsize_sedan, fraction: 1.0}]
  drivers:
    - {name: human, model: idm, fraction: 1.0, params: {v0_mps: 30, T_s: 1.2, s0_m: 2.0, a_mps2: 1.0, b_mps2: 1.5,
       delta: 4}, noise_mps2: 0.2 ${4:-}}
corridor:
  inflow: {flow_vph: $2, arrivals: poisson}
  on_ramp: {start_m: 3000, end_m: 3300, flow_vph: $3}
output: {trajectories: true, trajectory_interval_s: 1.0}
EOF
}
merge "$tmp/high.yaml" 3400 900
merge "$tmp/low.yaml" 2400 300
high_ok=0
if run "$tmp/high.yaml" -o "$tmp/high.h5" && run "$tmp/low.yaml" -o "$tmp/low.h5"; then
  high_ok=1
  check waves_upstream_at_high_demand_only $CHECK waves "$tmp/high.h5" "$tmp/low.h5" 500 3000 3500 300
else ko waves_upstream_at_high_demand_only "a run failed"; fi

# ------------------------------------------------------------------ b. cooperation off: the ramp jams
merge "$tmp/off.yaml" 3400 900 ", lane_change: {model: mobil, coop_decel_mps2: 0}"
if [ $high_ok = 1 ] && run "$tmp/off.yaml" -o "$tmp/off.h5"; then
  check cooperation_off_jams_the_ramp $CHECK coop_effect "$tmp/high.h5" "$tmp/off.h5" 500 3000 300
else ko cooperation_off_jams_the_ramp "a run failed"; fi

# ------------------------------------------------------------------ c. every step, recomputed
cat >"$tmp/step.yaml" <<EOF
name: merge_every_step
seed: 3
road: {type: corridor, length_m: 5000, lanes: 2, lane_rule: keep_right}
time: {duration_s: 400, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 60}
fleet:
  classes: [{class: midsize_sedan, fraction: 1.0}]
  drivers:
    - {name: human, model: idm, fraction: 0.7, params: {v0_mps: 30, T_s: 1.2, s0_m: 2.0, a_mps2: 1.0, b_mps2: 1.5,
       delta: 4}}
    - {name: slow, model: idm, fraction: 0.3, params: {v0_mps: 15, T_s: 1.2, s0_m: 2.0, a_mps2: 1.0, b_mps2: 1.5,
       delta: 4}, lane_change: {model: mobil, coop_decel_mps2: 3.0, merge_range_m: 150}}
corridor:
  inflow: {flow_vph: 3400, arrivals: poisson}
  on_ramp: {start_m: 3000, end_m: 3300, flow_vph: 900}
  detectors: {x_m: [1000, 3500], interval_s: 30}
output: {trajectories: true, trajectory_interval_s: 0.1}
EOF
if run "$tmp/step.yaml" -o "$tmp/step.h5"; then
  check cooperation_recomputed_every_step $CHECK accel "$tmp/step.h5"
  check mandatory_merges_recomputed $CHECK mandatory "$tmp/step.h5"
  check conservation_per_lane_and_ramp $CHECK conservation "$tmp/step.h5"
else ko cooperation_recomputed_every_step "run failed"; fi

# ------------------------------------------------------------------ d. threads and resume
# IDM with short headways (T = 0.1 s, v0 70 m/s) at a demand above what the entrance passes, all of it into lane 1
# (about 3.4 vehicles a second); MOBIL with a 5 m/s^2 threshold, so that few leave lane 1 on their own.
cat >"$tmp/big.yaml" <<EOF
name: merge_big
seed: 31
road: {type: corridor, length_m: 90000, lanes: 2}
time: {duration_s: 1400, dt_s: 0.2, output_interval_s: 5.0, warmup_s: 60}
fleet:
  classes: [{class: midsize_sedan, fraction: 1.0}]
  drivers:
    - {model: idm, fraction: 1.0, params: {v0_mps: 70, T_s: 0.1, s0_m: 0.5, a_mps2: 3.0, b_mps2: 1.5, delta: 4},
       noise_mps2: 0.2, lane_change: {model: mobil, threshold_mps2: 5, merge_range_m: 5000}}
corridor:
  inflow: {flow_vph: 30000, arrivals: poisson, insert_decel_mps2: 2, lane_shares: [1.0, 0.0]}
  on_ramp: {start_m: 5000, end_m: 10000, flow_vph: 1500}
  detectors: {x_m: [1000, 20000, 85000], interval_s: 60}
output: {trajectories: true, trajectory_interval_s: 10}
EOF
big_ok=0
if $BIN run "$tmp/big.yaml" -o "$tmp/big1.h5" --force --threads 1 -q >"$tmp/big1.log" 2>&1 &&
   run "$tmp/big.yaml" -o "$tmp/big2.h5" --threads 2; then
  big_ok=1
  check yields_with_threads $CHECK yields "$tmp/big1.h5" 4096 5
  if [ "$($PY -c 'import h5py,sys; print(h5py.File(sys.argv[1])["meta/threads"][()])' "$tmp/big2.h5")" = 2 ]; then
    check threads_1_vs_2_bit_identical_with_cooperation $PY tests/corridor_lanes_check.py identical "$tmp/big1.h5" \
      "$tmp/big2.h5" 4096
  else ko threads_1_vs_2_bit_identical_with_cooperation "the 2-thread run did not record 2 threads"; fi
else ko threads_1_vs_2_bit_identical_with_cooperation "run failed: $(tail -3 "$tmp/big1.log")"; fi
# SIGTERM once a checkpoint is written after a second (some hundreds of seconds of road time, yields under way),
# resumed on 1 thread: the 1-thread run's bytes.
if [ $big_ok = 1 ]; then
  $BIN run "$tmp/big.yaml" -q -o "$tmp/res.h5" --threads 2 --checkpoint-every 1 2>/dev/null & pid=$!
  pids+=("$pid")
  if wait_checkpoint "$tmp/res.h5" $pid && signal_running TERM $pid; then
    wait $pid; rc=$?
    before=$($PY -c 'import h5py,sys,numpy as np; f=h5py.File(sys.argv[1]); print(int(f["meta/steps_done"][()]),
             int(np.nansum(f["lanes/lane_changes"][()])))' "$tmp/res.h5.partial" 2>/dev/null)
    if [ $rc -eq 3 ] && [ "${before#* }" != 0 ] && $BIN run --resume "$tmp/res.h5" -q --threads 1; then
      check resume_with_cooperation_bit_identical $PY tests/corridor_lanes_check.py identical "$tmp/big1.h5" \
        "$tmp/res.h5" 4096
      echo "    (stopped at step ${before% *} of 7000 after ${before#* } lane changes)"
    else ko resume_with_cooperation_bit_identical "interrupted run exit $rc (want 3), steps and changes '$before'"; fi
  else wait $pid; ko resume_with_cooperation_bit_identical "the run ended before a checkpoint"; fi
else ko resume_with_cooperation_bit_identical "no reference run"; fi

# ------------------------------------------------------------------ e. refusals
bad() { # name, expected text, scenario
  local name=$1 want=$2 s=$3 msg rc
  msg=$($BIN run "$s" -q -o "$tmp/bad.h5" 2>&1); rc=$?
  if [ $rc -eq 2 ] && printf '%s' "$msg" | grep -qF -- "$want" && [ ! -e "$tmp/bad.h5" ] &&
     [ ! -e "$tmp/bad.h5.partial" ]; then ok "$name"; else ko "$name" "rc=$rc $msg"; fi
}
merge "$tmp/neg.yaml" 3400 900 ", lane_change: {model: mobil, coop_decel_mps2: -1}"
bad coop_decel_negative "fleet.drivers[0].lane_change.coop_decel_mps2" "$tmp/neg.yaml"
merge "$tmp/neg.yaml" 3400 900 ", lane_change: {model: mobil, merge_range_m: -5}"
bad merge_range_negative "fleet.drivers[0].lane_change.merge_range_m" "$tmp/neg.yaml"
