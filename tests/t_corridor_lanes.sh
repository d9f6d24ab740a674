#!/usr/bin/env bash
# Multi-lane corridors (road.lanes on road.type: corridor, corridor.inflow.lane_shares, MOBIL lane changes;
# src/core/corridor.c, docs/lanes.md, docs/corridors.md) through `wavefuel run`, each result checked by
# tests/corridor_lanes_check.py against something computed apart from it:
# a. lane changes off (every group `lane_change: {model: none}`): lane 0 of a 3-lane corridor equals, bit for bit, a
#    single-lane corridor with lane 0's share of the demand (Poisson arrivals, two classes, two groups,
#    heterogeneity, noise, grade and zones; random and interleaved placement): every trip, every trajectory point,
#    the lane's records; without any
#    randomness (deterministic arrivals, one class, one group) every lane l equals the single-lane corridor of its
#    share s_l q, serials l 2^40 + n; and two lanes with the same demand and noise do not drive the same trips;
# b. 1 thread and 2 threads give the same bytes on a corridor with lane changes and more than 4096 vehicles in a
#    lane (the kernel's and the decisions' threshold for threads);
# c. interrupted by SIGTERM (2 threads) after lane changes and resumed (1 thread): the bytes of the uninterrupted run;
# d. frames written every step: each lane ordered front first with positive gaps, the vehicles on the road those
#    /trips says entered and not exited, every lane change seen between frames counted in /trips and in the
#    record's /lanes/lane_changes, the cut-ins, pairs and records' lanes from the frames, detectors and Edie's
#    distance, no vehicle changing sooner than its group's min_interval_s, the ballistic update across changes; on
#    two lanes, three behind a slow downstream boundary, and three whose side lanes get no demand;
# e. unequal lane shares ([0.8, 0.2]) under the symmetric rule even out the lanes' densities downstream; with lane
#    changes off they do not;
# f. /lanes against /timeseries, /summary, /trips and the printed summary line;
# g. refusals: exit status 2, the key named, no file written.
set -u
cd "$(dirname "$0")/.." || exit 1
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
PY=/usr/bin/python3
CHECK="$PY tests/corridor_lanes_check.py"
# Threads that sleep while they wait: on a loaded machine spinning threads can take many times longer (results
# do not depend on it).
export OMP_WAIT_POLICY=passive
. tests/scaffold.sh

# ------------------------------------------------------------------ a. lanes off = independent single-lane corridors
# corridor FILE LANES-KEY INFLOW DRIVERS CLASSES [DURATION]: a 3 km corridor with a grade profile, a slow zone and
# trajectories every second; LANES-KEY is "lanes: N," or empty.
corridor() {
  cat >"$1" <<EOF
name: corridor_lanes
seed: 13
road:
  type: corridor
  length_m: 3000
  $2
  speed_limit_mps: 30
  grade: {points: [[0, 0], [1000, 0.02], [2000, -0.01], [3000, 0]]}
  zones:
    - {type: speed_limit, from_m: 1800, to_m: 2200, speed_limit_mps: 9}
    - {type: headway, from_m: 600, to_m: 900, factor: 1.3}
time: {duration_s: ${6:-400}, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 30}
fleet:
  classes: $5
  drivers:
$4
corridor:
  inflow: {$3}
  detectors: {x_m: [500, 2500], interval_s: 30}
output: {trajectories: true, trajectory_interval_s: 1.0}
EOF
}
MIX="[{class: midsize_sedan, fraction: 0.7}, {class: class8_tractor, fraction: 0.3}]"
OFF="lane_change: {model: none}"
RICH="    - {name: human, model: idm, fraction: 0.8, noise_mps2: 0.3, heterogeneity: {spread: {T_s: 0.1, v0_mps: 0.1}},
       $OFF}
    - {name: av, model: pi_saturation, fraction: 0.2, class: midsize_sedan, $OFF}"
corridor "$tmp/rich3.yaml" "lanes: 3" "flow_vph: 3600, arrivals: poisson, lane_shares: [0.5, 0.3, 0.2]" "$RICH" "$MIX"
corridor "$tmp/rich0.yaml" "" "flow_vph: 1800, arrivals: poisson" "$RICH" "$MIX"
if run "$tmp/rich3.yaml" -o "$tmp/rich3.h5" && run "$tmp/rich0.yaml" -o "$tmp/rich0.h5"; then
  check lanes_off_lane0_equals_single_corridor $CHECK same_lane "$tmp/rich3.h5" "$tmp/rich0.h5" 0
else ko lanes_off_lane0_equals_single_corridor "a run failed"; fi
# The same with interleaved placement (each lane its own deficit counters) and a leader outflow inside the road.
IL="--set fleet.placement=interleaved --set corridor.outflow.type=leader --set corridor.outflow.speed_mps=10
    --set corridor.outflow.offset_m=-1500"
if run "$tmp/rich3.yaml" -o "$tmp/rich3i.h5" $IL && run "$tmp/rich0.yaml" -o "$tmp/rich0i.h5" $IL; then
  check lanes_off_lane0_interleaved_leader $CHECK same_lane "$tmp/rich3i.h5" "$tmp/rich0i.h5" 0
else ko lanes_off_lane0_interleaved_leader "a run failed"; fi
# No randomness: deterministic arrivals, tractors only, one IDM group without noise or heterogeneity. The shares'
# products with q are written as decimals (1500, 900, 600); the engine multiplies the share by the cumulative demand.
PLAIN="    - {model: idm, fraction: 1.0, $OFF}"
TRUCKS="[{class: class8_tractor, fraction: 1.0}]"
corridor "$tmp/det3.yaml" "lanes: 3" "flow_vph: 3000, lane_shares: [0.5, 0.3, 0.2]" "$PLAIN" "$TRUCKS"
det_ok=1
run "$tmp/det3.yaml" -o "$tmp/det3.h5" || det_ok=0
for q in 1500 900 600; do
  corridor "$tmp/det_$q.yaml" "" "flow_vph: $q" "$PLAIN" "$TRUCKS"
  run "$tmp/det_$q.yaml" -o "$tmp/det_$q.h5" || det_ok=0
done
if [ $det_ok = 1 ]; then
  check lanes_off_deterministic_lane0 $CHECK same_lane "$tmp/det3.h5" "$tmp/det_1500.h5" 0
  check lanes_off_deterministic_lane1 $CHECK same_lane "$tmp/det3.h5" "$tmp/det_900.h5" 1
  check lanes_off_deterministic_lane2 $CHECK same_lane "$tmp/det3.h5" "$tmp/det_600.h5" 2
else ko lanes_off_deterministic "a run failed"; fi
# Two lanes with the same deterministic demand, one class, one noisy group: the n-th vehicles of both lanes that
# entered at the same instant meet the same road, so only the acceleration noise sets them apart; if both lanes drew
# the same noise (the ring keys lane l's noise from l 2^32 blocks so that they do not: docs/lanes.md) every such
# pair would burn the same fuel to the bit.
NOISY="    - {model: idm, fraction: 1.0, noise_mps2: 0.3, $OFF}"
corridor "$tmp/twins.yaml" "lanes: 2" "flow_vph: 3000, lane_shares: [0.5, 0.5]" "$NOISY" "$TRUCKS"
if run "$tmp/twins.yaml" -o "$tmp/twins.h5"; then check lanes_draw_their_own_noise $CHECK noise_apart "$tmp/twins.h5"
else ko lanes_draw_their_own_noise "run failed"; fi

# ------------------------------------------------------------------ b. threads
# A 90 km two-lane corridor at a demand above what the entrances pass: IDM with short headways (T = 0.1 s) fills
# each lane with more than 4096 vehicles after about 1500 s (the lanes reach about 4300 and 4250), Poisson arrivals,
# noise, heterogeneity, two classes, a lane-changing group among drivers who keep their lane, detectors and Edie.
cat >"$tmp/big.yaml" <<EOF
name: big_corridor_lanes
seed: 29
road: {type: corridor, length_m: 90000, lanes: 2}
time: {duration_s: 1700, dt_s: 0.2, output_interval_s: 5.0, warmup_s: 60}
fleet:
  classes:
    - {class: midsize_sedan, fraction: 0.8}
    - {class: compact_sedan, fraction: 0.2}
  drivers:
    - {model: idm, fraction: 0.8, params: {v0_mps: 60, T_s: 0.1, s0_m: 0.5, a_mps2: 3.0}, noise_mps2: 0.2,
       heterogeneity: {spread: {v0_mps: 0.05}}}
    - {model: idm, fraction: 0.2, params: {v0_mps: 50, T_s: 0.3, s0_m: 1.0, a_mps2: 2.0},
       lane_change: {model: mobil, politeness: 0.5, min_interval_s: 2}}
corridor:
  inflow: {flow_vph: 30000, arrivals: poisson, insert_decel_mps2: 2, lane_shares: [0.75, 0.25]}
  detectors: {x_m: [1000, 20000, 85000], interval_s: 60}
  edie: {dx_m: 500, dt_s: 60}
output: {trajectories: true, trajectory_interval_s: 60}
EOF
big_ok=0
if $BIN run "$tmp/big.yaml" -o "$tmp/big1.h5" --force --threads 1 >"$tmp/big1.log" 2>&1 &&
   run "$tmp/big.yaml" -o "$tmp/big2.h5" --threads 2; then
  big_ok=1
  if [ "$($PY -c 'import h5py,sys; print(h5py.File(sys.argv[1])["meta/threads"][()])' "$tmp/big2.h5")" = 2 ]; then
    check threads_1_vs_2_bit_identical $CHECK identical "$tmp/big1.h5" "$tmp/big2.h5" 4096
  else ko threads_1_vs_2_bit_identical "the 2-thread run did not record 2 threads"; fi
else ko threads_1_vs_2_bit_identical "run failed: $(tail -3 "$tmp/big1.log")"; fi

# ------------------------------------------------------------------ c. interrupted and resumed
# The same corridor on 2 threads, SIGTERM once a checkpoint is written after a second and a half (some 400 s of
# road time: thousands of lane changes made), resumed on 1 thread: the 1-thread run's bytes.
if [ $big_ok = 1 ]; then
  $BIN run "$tmp/big.yaml" -q -o "$tmp/res.h5" --threads 2 --checkpoint-every 1.5 2>/dev/null & pid=$!
  pids+=("$pid")
  if wait_checkpoint "$tmp/res.h5" $pid && signal_running TERM $pid; then
    wait $pid; rc=$?
    # the partial result's records so far (the rows not yet written are NaN)
    before=$($PY -c 'import h5py,sys,numpy as np; f=h5py.File(sys.argv[1]); print(int(f["meta/steps_done"][()]),
             int(np.nansum(f["lanes/lane_changes"][()])))' "$tmp/res.h5.partial" 2>/dev/null)
    if [ $rc -eq 3 ] && [ "${before#* }" != 0 ] && $BIN run --resume "$tmp/res.h5" -q --threads 1; then
      check resume_with_lane_changes_bit_identical $CHECK identical "$tmp/big1.h5" "$tmp/res.h5" 4096
      echo "    (stopped at step ${before% *} of 8500 after ${before#* } lane changes)"
    else ko resume_with_lane_changes_bit_identical "interrupted run exit $rc (want 3), steps and changes '$before'"; fi
  else wait $pid; ko resume_with_lane_changes_bit_identical "the run ended before a checkpoint"; fi
else ko resume_with_lane_changes_bit_identical "no reference run"; fi

# ------------------------------------------------------------------ d. physical checks, every step
# Two lanes, 70 / 30 % of 3000 veh/h; groups with min_interval_s 1 s and 2 s (10 and 20 steps).
TWO="    - {name: human, model: idm, fraction: 0.7, noise_mps2: 0.3, heterogeneity: {spread: {v0_mps: 0.1}}}
    - {name: slow, model: idm, fraction: 0.3, params: {v0_mps: 22}, lane_change: {model: mobil, min_interval_s: 2}}"
corridor "$tmp/every2.yaml" "lanes: 2" "flow_vph: 3000, arrivals: poisson, lane_shares: [0.7, 0.3]" "$TWO" "$MIX" 240
if $BIN run "$tmp/every2.yaml" -o "$tmp/every2.h5" --force --set output.trajectory_interval_s=0.1 >"$tmp/every2.log"
then
  check physical_two_lanes_every_step $CHECK physical "$tmp/every2.h5" 10,20
else ko physical_two_lanes_every_step "run failed"; fi
# Three lanes behind a downstream boundary at 8 m/s (a queue that fills the road), all demand in the middle lane.
THREE="    - {name: human, model: idm, fraction: 0.6, noise_mps2: 0.3}
    - {name: gipps, model: gipps, fraction: 0.4, lane_change: {model: mobil, politeness: 0.5, min_interval_s: 1.5}}"
corridor "$tmp/every3.yaml" "lanes: 3" "flow_vph: 3500, arrivals: poisson, lane_shares: [0.2, 0.6, 0.2]" "$THREE" \
  "$MIX" 300
if run "$tmp/every3.yaml" -o "$tmp/every3.h5" --set output.trajectory_interval_s=0.1 \
     --set corridor.outflow.type=speed --set corridor.outflow.speed_mps=8; then
  check physical_three_lanes_queue_every_step $CHECK physical "$tmp/every3.h5" 10,15
else ko physical_three_lanes_queue_every_step "run failed"; fi

# All the demand in the middle lane of three (lane_shares [0, 1, 0]): the side lanes fill only by lane changes, the
# first ones into an empty lane, then ahead of its front or behind its back.
corridor "$tmp/middle.yaml" "lanes: 3" "flow_vph: 2500, arrivals: poisson, lane_shares: [0, 1, 0]" "$TWO" "$MIX" 240
if run "$tmp/middle.yaml" -o "$tmp/middle.h5" --set output.trajectory_interval_s=0.1; then
  check physical_side_lanes_fill_every_step $CHECK physical "$tmp/middle.h5" 10,20
else ko physical_side_lanes_fill_every_step "run failed"; fi

# ------------------------------------------------------------------ e. unequal shares even out
# 1600 veh/h of sedans on 6 km, 80 % entering lane 0 (1280 veh/h: no queue at either entrance, at most 5 waiting):
# over the second half of the road and the last 600 s, MOBIL (symmetric) brings lane 0's share of the density from
# the entry's 0.8 to within 0.1 of an even split (0.53 when written); without lane changes it stays more than 0.25
# away (0.82: the busier lane is also the slower one).
EVEN="    - {model: idm, fraction: 1.0, noise_mps2: 0.2}"
SEDANS="[{class: midsize_sedan, fraction: 1.0}]"
corridor "$tmp/even.yaml" "lanes: 2" "flow_vph: 1600, arrivals: poisson, lane_shares: [0.8, 0.2]" "$EVEN" "$SEDANS" 900
sed -e 's/length_m: 3000/length_m: 6000/' -e 's/\[3000, 0\]/[6000, 0]/' "$tmp/even.yaml" >"$tmp/even6.yaml"
sed 's/noise_mps2: 0.2}/noise_mps2: 0.2, lane_change: {model: none}}/' "$tmp/even6.yaml" >"$tmp/even6_off.yaml"
if run "$tmp/even6.yaml" -o "$tmp/even.h5" && run "$tmp/even6_off.yaml" -o "$tmp/even_off.h5"; then
  check unequal_shares_even_out $CHECK redistribute "$tmp/even.h5" 3000 300 lt 0.1
  check unequal_shares_stay_without_changes $CHECK redistribute "$tmp/even_off.h5" 3000 300 gt 0.25
else ko unequal_shares_even_out "run failed"; fi

# ------------------------------------------------------------------ f. /lanes adds up
for r in every2 every3 middle big1; do
  if [ -f "$tmp/$r.h5" ]; then
    log=""; [ -f "$tmp/$r.log" ] && log="$tmp/$r.log"
    check "lanes_sums_$r" $CHECK lanes_sums "$tmp/$r.h5" $log
  else ko "lanes_sums_$r" "no result"; fi
done

# ------------------------------------------------------------------ g. refusals
bad() { # name, expected text, scenario
  local name=$1 want=$2 s=$3 msg rc
  msg=$($BIN run "$s" -q -o "$tmp/bad.h5" 2>&1); rc=$?
  if [ $rc -eq 2 ] && printf '%s' "$msg" | grep -qF -- "$want" && [ ! -e "$tmp/bad.h5" ] &&
     [ ! -e "$tmp/bad.h5.partial" ]; then ok "$name"; else ko "$name" "rc=$rc $msg"; fi
}
shares() { sed "s/lane_shares: \[[^]]*\]/lane_shares: $1/" "$tmp/det3.yaml" >"$tmp/shares.yaml"; }
shares "[0.5, 0.5]"; bad lane_shares_wrong_length "corridor.inflow.lane_shares" "$tmp/shares.yaml"
shares "[0.5, 0.3, 0.1]"; bad lane_shares_sum_below_1 "corridor.inflow.lane_shares" "$tmp/shares.yaml"
shares "[0.5, 0.3, 0.2001]"; bad lane_shares_sum_above_1 "corridor.inflow.lane_shares" "$tmp/shares.yaml"
shares "[0.6, 0.5, -0.1]"; bad lane_shares_negative "corridor.inflow.lane_shares[2]" "$tmp/shares.yaml"
shares "0.5"; bad lane_shares_not_a_list "corridor.inflow.lane_shares" "$tmp/shares.yaml"
sed 's/lanes: 3/lanes: 9/' "$tmp/det3.yaml" >"$tmp/nine.yaml"
bad corridor_lanes_nine "road.lanes" "$tmp/nine.yaml"
sed '/lanes: 3/d' "$tmp/det3.yaml" >"$tmp/one.yaml"
bad lane_shares_on_one_lane "corridor.inflow.lane_shares" "$tmp/one.yaml"
