#!/usr/bin/env bash
# Off-ramps (corridor.off_ramp {at_m, share, approach_m}; src/core/corridor.c phase_offramp, offramp_exit and the draw
# in try_insert; src/core/lanes.c approaching, rule_of, asks; docs/corridors.md) through `wavefuel run`, each result
# checked by tests/offramp_check.py against something computed apart from it:
# a. conservation at every record and at the end, from /trips alone (entered = exited at L + off-ramp exits + on the
#    road; /summary's counters and trip means from the /trips rows), on three lanes and on one;
# b. where and how vehicles leave, from frames written every step: who is bound for the off-ramp recomputed from the
#    seed (the checker's own Philox4x32-10); a bound vehicle whose front reaches at_m in the exit lane leaves at the end
#    of that step (its /trips row: completed 2, exit lane, exit time, distance at_m - entry + at most one step's
#    travel), one in another lane misses it (counted in /summary/missed_exits) and drives on to L; nobody else
#    leaves before L; on the approach a bound vehicle changes lanes only toward the exit lane, and takes at once a
#    wide gap in the lane toward it (200 m free behind, 120 m ahead: safe whatever its incentive); with a short
#    approach (approach_m 50) many miss it; with an on-ramp the exit lane is lane 1; where the run differs first from
#    one where nobody yields, the only vehicles whose acceleration differs are right behind a bound vehicle on its
#    approach in the lane beside it (the follower it asked), each one lowered;
# c. the share of the vehicles reaching at_m that were bound for it, within 4 binomial standard deviations; share 0
#    equals the run without an off-ramp bit for bit (but for the off-ramp's two counters), on three lanes, on one and
#    with an on-ramp; share 1 on one lane: everybody leaves at at_m, nobody reaches L;
# d. one lane without randomness on the road: each vehicle's trajectory equals the share-0 run's bit for bit until a
#    vehicle ahead of it leaves (whole trips for the vehicles ahead of the first exit);
# e. with an on-ramp whose merge lane ends on the approach, a vehicle bound for the off-ramp in the merge lane takes
#    a wide gap beside it at once, and nobody stays in the merge lane much longer than with share 0;
# f. 1 and 2 threads give the same bytes with more than 4096 vehicles in a lane while vehicles leave and miss the
#    off-ramp; interrupted by SIGTERM after off-ramp exits and resumed: the bytes of the uninterrupted run;
# g. refusals: exit status 2, the key named, no file written.
set -u
cd "$(dirname "$0")/.." || exit 1
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
PY=/usr/bin/python3
CHECK="$PY tests/offramp_check.py"
# Threads that sleep while they wait (results do not depend on it).
export OMP_WAIT_POLICY=passive
. tests/scaffold.sh

# ------------------------------------------------------------------ scenarios
# three FILE OFF-RAMP [EXTRA]: 3 km, three lanes of 4500 veh/h (Poisson, unequal shares), sedans and tractors, a noisy
# group and a slow one that changes lanes less often; trajectories every step. OFF-RAMP: the corridor.off_ramp line.
three() {
  cat >"$1" <<EOF
name: offramp_three
seed: 7
road: {type: corridor, length_m: 3000, lanes: 3, speed_limit_mps: 30}
time: {duration_s: ${4:-600}, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 30}
fleet:
  classes:
    - {class: midsize_sedan, fraction: 0.8}
    - {class: class8_tractor, fraction: 0.2}
  drivers:
    - {name: human, model: idm, fraction: 0.8, noise_mps2: 0.3, heterogeneity: {spread: {v0_mps: 0.1}}}
    - {name: slow, model: idm, fraction: 0.2, params: {v0_mps: 24}, lane_change: {model: mobil, min_interval_s: 2}}
corridor:
  inflow: {flow_vph: 4500, arrivals: poisson, lane_shares: [0.3, 0.4, 0.3]}
  $2
  $3
  detectors: {x_m: [500, 2500], interval_s: 30}
output: {trajectories: true, trajectory_interval_s: 0.1}
EOF
}
# one FILE OFF-RAMP: one lane of 2.5 km, 1900 veh/h (Poisson), a slow zone after the off-ramp, 2000 s (about 1000
# vehicles), a noisy heterogeneous IDM group; trajectories every step.
one() {
  cat >"$1" <<EOF
name: offramp_one
seed: 11
road: {type: corridor, length_m: 2500, speed_limit_mps: 30,
       zones: [{type: speed_limit, from_m: 1700, to_m: 2000, speed_limit_mps: 12}]}
time: {duration_s: 2000, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 30}
fleet:
  classes:
    - {class: midsize_sedan, fraction: 0.8}
    - {class: class8_tractor, fraction: 0.2}
  drivers:
    - {model: idm, fraction: 1.0, noise_mps2: 0.3, heterogeneity: {spread: {v0_mps: 0.1}}}
corridor:
  inflow: {flow_vph: 1900, arrivals: poisson}
  $2
  detectors: {x_m: [500, 1600], interval_s: 60}
output: {trajectories: true, trajectory_interval_s: 0.1}
EOF
}
OFF3="off_ramp: {at_m: 2000, share: 0.3}"                    # approach_m: its default, 1000 m
OFF1="off_ramp: {at_m: 1500, share: 0.3, approach_m: 400}"

# ------------------------------------------------------------------ a, b, c. three lanes
three "$tmp/three.yaml" "$OFF3" ""
if run "$tmp/three.yaml" -o "$tmp/three.h5"; then
  check conservation_three_lanes $CHECK conserve "$tmp/three.h5"
  check exits_three_lanes_every_step $CHECK frames "$tmp/three.h5"
  check share_three_lanes $CHECK share "$tmp/three.h5"
else ko three_lanes "run failed"; fi
# cooperation: the same run where nobody yields (coop_decel_mps2: 0 in both groups)
sed -e 's/v0_mps: 0.1}}}/v0_mps: 0.1}}, lane_change: {model: mobil, coop_decel_mps2: 0}}/' \
    -e 's/min_interval_s: 2}/min_interval_s: 2, coop_decel_mps2: 0}/' "$tmp/three.yaml" >"$tmp/nocoop.yaml"
if [ "$(grep -c coop_decel_mps2 "$tmp/nocoop.yaml")" = 2 ] && run "$tmp/nocoop.yaml" -o "$tmp/nocoop.h5"; then
  check cooperation_asked_on_the_approach $CHECK coop "$tmp/three.h5" "$tmp/nocoop.h5"
else ko cooperation_asked_on_the_approach "run failed"; fi
# share 0 against no off-ramp (trajectories every second: the same for both)
three "$tmp/zero3.yaml" "off_ramp: {at_m: 2000, share: 0}" ""
three "$tmp/none3.yaml" "" ""
if run "$tmp/zero3.yaml" -o "$tmp/zero3.h5" --set output.trajectory_interval_s=1 &&
   run "$tmp/none3.yaml" -o "$tmp/none3.h5" --set output.trajectory_interval_s=1; then
  check share0_equals_no_offramp_three_lanes $CHECK zero_equals "$tmp/zero3.h5" "$tmp/none3.h5"
else ko share0_equals_no_offramp_three_lanes "a run failed"; fi
# missed exits: an approach of 50 m, a larger share
three "$tmp/miss.yaml" "off_ramp: {at_m: 1500, share: 0.4, approach_m: 50}" "" 400
if run "$tmp/miss.yaml" -o "$tmp/miss.h5"; then
  check missed_exits_drive_on $CHECK frames "$tmp/miss.h5"
  check conservation_missed_exits $CHECK conserve "$tmp/miss.h5"
else ko missed_exits_drive_on "run failed"; fi

# the mandatory rule: sparse traffic (1200 veh/h), 60 % bound; wide gaps toward the exit lane are taken at once
three "$tmp/sparse.yaml" "off_ramp: {at_m: 2000, share: 0.6}" "" 900
if run "$tmp/sparse.yaml" -o "$tmp/sparse.h5" --set corridor.inflow.flow_vph=1200; then
  check mandatory_changes_sparse $CHECK frames "$tmp/sparse.h5" 10
else ko mandatory_changes_sparse "run failed"; fi

# ------------------------------------------------------------------ a, b, c. one lane
one "$tmp/one.yaml" "$OFF1"
if run "$tmp/one.yaml" -o "$tmp/one.h5"; then
  check conservation_one_lane $CHECK conserve "$tmp/one.h5"
  check exits_one_lane_every_step $CHECK frames "$tmp/one.h5"
  check share_one_lane $CHECK share "$tmp/one.h5"
else ko one_lane "run failed"; fi
one "$tmp/zero1.yaml" "off_ramp: {at_m: 1500, share: 0}"
one "$tmp/none1.yaml" ""
if run "$tmp/zero1.yaml" -o "$tmp/zero1.h5" --set time.duration_s=600 &&
   run "$tmp/none1.yaml" -o "$tmp/none1.h5" --set time.duration_s=600; then
  check share0_equals_no_offramp_one_lane $CHECK zero_equals "$tmp/zero1.h5" "$tmp/none1.h5"
else ko share0_equals_no_offramp_one_lane "a run failed"; fi
if run "$tmp/one.yaml" -o "$tmp/all1.h5" --set corridor.off_ramp.share=1 --set time.duration_s=600; then
  check share1_one_lane_all_leave $CHECK all_leave "$tmp/all1.h5"
  check share1_one_lane_every_step $CHECK frames "$tmp/all1.h5"
  check conservation_share1 $CHECK conserve "$tmp/all1.h5"
else ko share1_one_lane_all_leave "run failed"; fi

# ------------------------------------------------------------------ d. one lane, nothing random on the road
# Deterministic arrivals, no noise nor heterogeneity (class and group draws are keyed by serial: the same in both
# runs), two car-following models, a slow zone after the off-ramp; 8 % take it.
cat >"$tmp/det.yaml" <<EOF
name: offramp_det
seed: 3
road: {type: corridor, length_m: 3000, speed_limit_mps: 30,
       zones: [{type: speed_limit, from_m: 2200, to_m: 2600, speed_limit_mps: 10}]}
time: {duration_s: 700, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 30}
fleet:
  classes:
    - {class: midsize_sedan, fraction: 0.7}
    - {class: class8_tractor, fraction: 0.3}
  drivers:
    - {model: idm, fraction: 0.7}
    - {model: gipps, fraction: 0.3}
corridor:
  inflow: {flow_vph: 2000}
  off_ramp: {at_m: 1800, share: 0.08}
output: {trajectories: true, trajectory_interval_s: 0.1}
EOF
if run "$tmp/det.yaml" -o "$tmp/det.h5" && run "$tmp/det.yaml" -o "$tmp/det0.h5" --set corridor.off_ramp.share=0; then
  check vehicles_ahead_unaffected $CHECK ahead "$tmp/det.h5" "$tmp/det0.h5"
else ko vehicles_ahead_unaffected "a run failed"; fi

# ------------------------------------------------------------------ b, c, e. with an on-ramp (the exit lane is lane 1)
# Two main lanes and a 500 m merge lane from the entrance; the off-ramp at 1200 m with the default 1000 m approach:
# the merge lane's last 300 m lie on the approach. bound_vehicles_leave_the_merge_lane fails at acaac2e: on the
# approach src/core/lanes.c lets a bound vehicle change only to the right (decide_block skips d == 1 and every
# vehicle with l <= exit_lane; asks() asks only from lanes beyond the exit lane), so one in the merge lane (below
# the exit lane) neither changes nor asks, and stops at the merge lane's end for good.
cat >"$tmp/ramp.yaml" <<EOF
name: offramp_onramp
seed: 7
road: {type: corridor, length_m: 3000, lanes: 2, speed_limit_mps: 30}
time: {duration_s: 400, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 30}
fleet:
  classes: [{class: midsize_sedan, fraction: 1.0}]
  drivers:
    - {name: human, model: idm, fraction: 1.0, noise_mps2: 0.3}
corridor:
  inflow: {flow_vph: 1500, arrivals: poisson}
  on_ramp: {start_m: 0, end_m: 500, flow_vph: 400}
  off_ramp: {at_m: 1200, share: 0.5}
output: {trajectories: true, trajectory_interval_s: 0.1}
EOF
sed '/off_ramp/d' "$tmp/ramp.yaml" >"$tmp/ramp_none.yaml"
sed 's/share: 0.5/share: 0/' "$tmp/ramp.yaml" >"$tmp/ramp_zero.yaml"
if run "$tmp/ramp.yaml" -o "$tmp/ramp.h5" && run "$tmp/ramp_zero.yaml" -o "$tmp/ramp0.h5" &&
   run "$tmp/ramp_none.yaml" -o "$tmp/ramp_none.h5"; then
  check conservation_with_on_ramp $CHECK conserve "$tmp/ramp.h5"
  check exits_with_on_ramp_from_lane_1 $CHECK frames "$tmp/ramp.h5"
  check share0_equals_no_offramp_on_ramp $CHECK zero_equals "$tmp/ramp0.h5" "$tmp/ramp_none.h5"
  check bound_vehicles_leave_the_merge_lane $CHECK merge "$tmp/ramp.h5" "$tmp/ramp0.h5"
else ko with_on_ramp "a run failed"; fi

# ------------------------------------------------------------------ f. threads
# A 90 km two-lane corridor: all the demand in lane 0 (36000 veh/h asked, about 3.6 veh/s pass the entrance), 90 %
# of the drivers hold their lane (lane_change: none), 10 % change by MOBIL; lane 0 holds more than 4096 vehicles (the
# kernel's threshold for threads) from about t = 1300 s while the off-ramp at 65 km takes 30 % (from t = 980 s) and
# lane changers in lane 1 miss it.
cat >"$tmp/big.yaml" <<EOF
name: big_offramp
seed: 29
road: {type: corridor, length_m: 90000, lanes: 2}
time: {duration_s: 1450, dt_s: 0.2, output_interval_s: 5.0, warmup_s: 60}
fleet:
  classes:
    - {class: compact_sedan, fraction: 1.0}
  drivers:
    - {model: idm, fraction: 0.9, params: {v0_mps: 70, T_s: 0.1, s0_m: 0.5, a_mps2: 3.0}, noise_mps2: 0.2,
       heterogeneity: {spread: {v0_mps: 0.05}}, lane_change: {model: none}}
    - {model: idm, fraction: 0.1, params: {v0_mps: 50, T_s: 0.3, s0_m: 1.0, a_mps2: 2.0},
       lane_change: {model: mobil, politeness: 0.5, min_interval_s: 2}}
corridor:
  inflow: {flow_vph: 36000, arrivals: poisson, insert_decel_mps2: 4, lane_shares: [1, 0]}
  off_ramp: {at_m: 65000, share: 0.3, approach_m: 1500}
  detectors: {x_m: [1000, 20000, 70000], interval_s: 60}
  edie: {dx_m: 1000, dt_s: 60}
output: {trajectories: true, trajectory_interval_s: 100}
EOF
if $BIN run "$tmp/big.yaml" -o "$tmp/big1.h5" --force -q --threads 1 &&
   run "$tmp/big.yaml" -o "$tmp/big2.h5" --threads 2; then
  if [ "$($PY -c 'import h5py,sys; print(h5py.File(sys.argv[1])["meta/threads"][()])' "$tmp/big2.h5")" = 2 ]; then
    check threads_1_vs_2_bit_identical $CHECK identical "$tmp/big1.h5" "$tmp/big2.h5" 4096
  else ko threads_1_vs_2_bit_identical "the 2-thread run did not record 2 threads"; fi
else ko threads_1_vs_2_bit_identical "a run failed"; fi

# ------------------------------------------------------------------ f. interrupted and resumed
# The three-lane corridor for an hour with the off-ramp at 1 km (its first exits within a minute of road time) and a
# 300 m approach (missed exits), trajectories every 5 s: 2 threads, SIGTERM once a checkpoint is written, resumed on
# 1 thread, against the uninterrupted 1-thread run.
three "$tmp/res.yaml" "off_ramp: {at_m: 1000, share: 0.3, approach_m: 300}" "" 3600
sed -i 's/trajectory_interval_s: 0.1/trajectory_interval_s: 5/' "$tmp/res.yaml"
if $BIN run "$tmp/res.yaml" -o "$tmp/res1.h5" --force -q --threads 1; then
  $BIN run "$tmp/res.yaml" -q -o "$tmp/res.h5" --threads 2 --checkpoint-every 0.3 2>/dev/null & pid=$!
  pids+=("$pid")
  if wait_checkpoint "$tmp/res.h5" $pid && signal_running TERM $pid; then
    wait $pid; rc=$?
    before=$($CHECK interrupted "$tmp/res.h5.partial" 2>/dev/null)
    if [ $rc -eq 3 ] && [ -n "$before" ] && [ "${before#* }" != 0 ] && $BIN run --resume "$tmp/res.h5" -q --threads 1
    then
      check resume_with_offramp_bit_identical $CHECK identical "$tmp/res1.h5" "$tmp/res.h5" 0
      echo "    (stopped at step ${before% *} of 36000 after ${before#* } off-ramp exits)"
    else ko resume_with_offramp_bit_identical "interrupted run exit $rc (want 3), steps and exits '$before'"; fi
  else wait $pid; ko resume_with_offramp_bit_identical "the run ended before a checkpoint"; fi
else ko resume_with_offramp_bit_identical "no reference run"; fi

# ------------------------------------------------------------------ g. refusals
bad() { # name, expected text, scenario, [--set ...]
  local name=$1 want=$2 s=$3 msg rc
  shift 3
  msg=$($BIN run "$s" -q -o "$tmp/bad.h5" "$@" 2>&1); rc=$?
  if [ $rc -eq 2 ] && printf '%s' "$msg" | grep -qF -- "$want" && [ ! -e "$tmp/bad.h5" ] &&
     [ ! -e "$tmp/bad.h5.partial" ]; then ok "$name"; else ko "$name" "rc=$rc $msg"; fi
}
S=$tmp/zero3.yaml
bad at_m_zero corridor.off_ramp.at_m "$S" --set corridor.off_ramp.at_m=0
bad at_m_at_L corridor.off_ramp.at_m "$S" --set corridor.off_ramp.at_m=3000
bad at_m_beyond_L corridor.off_ramp.at_m "$S" --set corridor.off_ramp.at_m=3500
bad at_m_negative corridor.off_ramp.at_m "$S" --set corridor.off_ramp.at_m=-5
bad share_negative corridor.off_ramp.share "$S" --set corridor.off_ramp.share=-0.1
bad share_above_1 corridor.off_ramp.share "$S" --set corridor.off_ramp.share=1.5
bad approach_negative corridor.off_ramp.approach_m "$S" --set corridor.off_ramp.approach_m=-1
three "$tmp/no_at.yaml" "off_ramp: {share: 0.3}" ""
bad at_m_missing "'at_m'" "$tmp/no_at.yaml"
three "$tmp/no_share.yaml" "off_ramp: {at_m: 2000}" ""
bad share_missing "'share'" "$tmp/no_share.yaml"
three "$tmp/typo.yaml" "off_ramp: {at_m: 2000, share: 0.3, aproach_m: 100}" ""
bad unknown_key_suggested "corridor.off_ramp.aproach_m' (did you mean 'approach_m'?)" "$tmp/typo.yaml"
three "$tmp/drop.yaml" "$OFF3" "lane_drops: [{lane: 0, at_m: 1500}]"
bad exit_lane_dropped_before corridor.off_ramp "$tmp/drop.yaml"
three "$tmp/drop_at.yaml" "$OFF3" "lane_drops: [{lane: 0, at_m: 2000}]"
bad exit_lane_dropped_at_it corridor.off_ramp "$tmp/drop_at.yaml"
three "$tmp/drop_ramp.yaml" "$OFF3" "on_ramp: {start_m: 0, end_m: 400, flow_vph: 300}
  lane_drops: [{lane: 1, at_m: 1500}]"
bad exit_lane_1_dropped_with_on_ramp "leaves lane 1" "$tmp/drop_ramp.yaml"
# a lane drop after it, and the leftmost lane dropped before it, are fine
three "$tmp/drop_after.yaml" "$OFF3" "lane_drops: [{lane: 0, at_m: 2500}, {lane: 2, at_m: 1000}]" 60
if msg=$($BIN run "$tmp/drop_after.yaml" -q -o "$tmp/ok.h5" 2>&1) && [ -e "$tmp/ok.h5" ]; then
  ok drops_elsewhere_accepted
else ko drops_elsewhere_accepted "$msg"; fi
