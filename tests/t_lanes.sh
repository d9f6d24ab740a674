#!/usr/bin/env bash
# Multi-lane rings (road.lanes, MOBIL lane changes; src/core/lanes.c) through `wavefuel run`, each result checked by
# tests/lanes_check.py against something computed apart from it:
# a. lane changes off (every group `lane_change: {model: none}`): each lane of a 3-lane ring equals, bit for bit, a
#    single-lane ring of the same vehicles (noise, heterogeneity and a perturbation only in lane 0, whose noise is a
#    single-lane ring's);
# b. symmetric rule: 45/15 vehicles on two lanes settle to equal counts (|n0 - n1| <= 2 over the last third);
# c. keep_right at low density: the right lane carries most vehicles; symmetric at the same density does not;
# d. 1 thread and 2 threads give the same bytes on a 13000-vehicle, 3-lane ring with lane changes;
# e. interrupted by SIGTERM and resumed: the bytes of the uninterrupted run;
# f. every frame (written every step): positions in each lane ordered with positive gaps, vehicles conserved,
#    the lane changes in /vehicles equal to those seen between frames, each vehicle's ballistic update across its
#    changes, its distance from the frames, the records' speeds and gaps from the frames, and no vehicle changing
#    again sooner than its group's min_interval_s (1 s, 2 s: 10, 20 steps);
# g. refusals: exit status 2, the key named, no file written;
# h. every step's lane changes of all-IDM rings (symmetric, 3 lanes, keep_right) equal MOBIL recomputed from the
#    frames in numpy.
set -u
cd "$(dirname "$0")/.." || exit 1
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
PY=/usr/bin/python3
CHECK="$PY tests/lanes_check.py"
. tests/scaffold.sh

# ------------------------------------------------------------------ a. lanes off = independent single-lane rings
# Lane 0: vehicles 0-19, IDM with noise, heterogeneity and vehicle 3 perturbed; lane 1: 20-34, IDM and OVM
# alternating; lane 2: 35-44, Gipps and IDM. Sedans and tractors mixed in every lane. All start at rest, so every
# lane's dynamics are not trivial. Each single-lane ring holds one lane's vehicles in the same order, with the
# same classes and models, renumbered from 0.
seq_csv() { seq -s, "$@"; }
cat >"$tmp/off3.yaml" <<EOF
name: lanes_off
seed: 7
road: {length_m: 900, lanes: 3}
time: {duration_s: 60, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 10}
fleet:
  vehicles: 45
  lane_counts: [20, 15, 10]
  placement: explicit
  classes:
    - {class: midsize_sedan, indices: [$(seq_csv 0 2 18),$(seq_csv 21 2 33),$(seq_csv 35 3 44)]}
    - {class: class8_tractor, indices: [$(seq_csv 1 2 19),$(seq_csv 20 2 34),36,37,39,40,42,43]}
  drivers:
    - {name: noisy, model: idm, noise_mps2: 0.4, heterogeneity: {spread: {T_s: 0.1, v0_mps: 0.1}},
       indices: [$(seq_csv 0 19)], lane_change: {model: none}}
    - {name: idm1, model: idm, params: {T_s: 1.4}, indices: [$(seq_csv 20 2 34),$(seq_csv 36 2 44)],
       lane_change: {model: none}}
    - {name: ovm1, model: ovm, indices: [$(seq_csv 21 2 33)], lane_change: {model: none}}
    - {name: gipps2, model: gipps, indices: [$(seq_csv 35 2 43)], lane_change: {model: none}}
initial: {state: rest, perturbation: {vehicle: 3, dv_mps: 2}}
output: {trajectories: true, trajectory_interval_s: 0.5}
EOF
# single_ring FILE N "SEDANS" "TRACTORS" DRIVERS-YAML [INITIAL-EXTRA]
single_ring() {
  cat >"$1" <<EOF
name: lane_alone
seed: 7
road: {length_m: 900}
time: {duration_s: 60, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 10}
fleet:
  vehicles: $2
  placement: explicit
  classes:
    - {class: midsize_sedan, indices: [$3]}
    - {class: class8_tractor, indices: [$4]}
  drivers:
$5
initial: {state: rest${6:-}}
output: {trajectories: true, trajectory_interval_s: 0.5}
EOF
}
NOISY="{name: noisy, model: idm, noise_mps2: 0.4, heterogeneity: {spread: {T_s: 0.1, v0_mps: 0.1}}"
single_ring "$tmp/lane0.yaml" 20 "$(seq_csv 0 2 18)" "$(seq_csv 1 2 19)" "    - $NOISY, indices: [$(seq_csv 0 19)]}" \
  ", perturbation: {vehicle: 3, dv_mps: 2}"
single_ring "$tmp/lane1.yaml" 15 "$(seq_csv 1 2 13)" "$(seq_csv 0 2 14)" \
  "    - {name: idm1, model: idm, params: {T_s: 1.4}, indices: [$(seq_csv 0 2 14)]}
    - {name: ovm1, model: ovm, indices: [$(seq_csv 1 2 13)]}"
single_ring "$tmp/lane2.yaml" 10 "$(seq_csv 0 3 9)" "1,2,4,5,7,8" \
  "    - {name: idm1, model: idm, params: {T_s: 1.4}, indices: [$(seq_csv 1 2 9)]}
    - {name: gipps2, model: gipps, indices: [$(seq_csv 0 2 8)]}"
if run "$tmp/off3.yaml" -o "$tmp/off3.h5" && run "$tmp/lane0.yaml" -o "$tmp/lane0.h5" &&
   run "$tmp/lane1.yaml" -o "$tmp/lane1.h5" && run "$tmp/lane2.yaml" -o "$tmp/lane2.h5"; then
  check lanes_off_lane0_equals_single_ring $CHECK same_lane "$tmp/off3.h5" "$tmp/lane0.h5" 0 20
  check lanes_off_lane1_equals_single_ring $CHECK same_lane "$tmp/off3.h5" "$tmp/lane1.h5" 20 15
  check lanes_off_lane2_equals_single_ring $CHECK same_lane "$tmp/off3.h5" "$tmp/lane2.h5" 35 10
else
  ko lanes_off_equals_single_rings "a run failed"
fi

# ------------------------------------------------------------------ b. symmetric rule: equal densities
two_lane() { # FILE RULE VEHICLES "COUNTS" LENGTH DURATION TRAJ-INTERVAL
  cat >"$1" <<EOF
name: two_lanes
seed: ${8:-1}
road: {length_m: $5, lanes: 2, lane_rule: $2}
time: {duration_s: $6, dt_s: 0.1, output_interval_s: 1.0}
fleet:
  vehicles: $3
  lane_counts: [$4]
  classes: [{class: midsize_sedan, fraction: 1.0}]
  drivers:
    - {model: idm, fraction: 1.0, noise_mps2: 0.3}
output: {trajectories: true, trajectory_interval_s: $7}
EOF
}
two_lane "$tmp/sym.yaml" symmetric 60 "45, 15" 3000 600 10
if run "$tmp/sym.yaml" -o "$tmp/sym.h5"; then
  check symmetric_equalises_densities $CHECK equalise "$tmp/sym.h5" 2
else ko symmetric_equalises_densities "run failed"; fi

# ------------------------------------------------------------------ c. keep right at low density
# 24 vehicles on 3000 m (one every 250 m per lane): a change costs little (halving a 250 m gap at 30 m/s moves IDM's
# interaction term (s*/s)^2 from about 0.016 to 0.07 m/s^2), less than keep_right's net bias to the right
# (Δa_bias - Δa_th = 0.2 m/s^2) and much less than the symmetric threshold needs as a gain (0.1 m/s^2).
# Lanes start 11/13 (not 12/12: equal counts would put the lanes' vehicles side by side, where no change is safe).
two_lane "$tmp/kr.yaml" keep_right 24 "11, 13" 3000 600 1 2
two_lane "$tmp/krsym.yaml" symmetric 24 "11, 13" 3000 600 1 2
if run "$tmp/kr.yaml" -o "$tmp/kr.h5" && run "$tmp/krsym.yaml" -o "$tmp/krsym.h5"; then
  check keep_right_fills_right_lane $CHECK lane_share "$tmp/kr.h5" gt 0.65
  check symmetric_low_density_no_right_preference $CHECK lane_share "$tmp/krsym.h5" le 0.5
else ko keep_right_fills_right_lane "run failed"; fi

# ------------------------------------------------------------------ d. threads
# 13000 vehicles in 3 lanes (6500, 4500, 2000: two lanes above the kernel's 4096-vehicle threshold for threads,
# the decisions over all 13000), unequal densities so that thousands of vehicles change lanes in 30 s.
cat >"$tmp/big.yaml" <<EOF
name: big_lanes
seed: 11
road: {length_m: 200000, lanes: 3}
time: {duration_s: 30, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 5}
fleet:
  vehicles: 13000
  lane_counts: [6500, 4500, 2000]
  classes:
    - {class: midsize_sedan, fraction: 0.8}
    - {class: class8_tractor, fraction: 0.2}
  drivers:
    - {model: idm, fraction: 0.7, noise_mps2: 0.3, heterogeneity: {spread: {v0_mps: 0.1}}}
    - {model: gipps, fraction: 0.3, lane_change: {model: mobil, politeness: 0.5, min_interval_s: 2}}
output: {trajectories: true, trajectory_interval_s: 5}
EOF
if run "$tmp/big.yaml" -o "$tmp/big1.h5" --threads 1 && run "$tmp/big.yaml" -o "$tmp/big2.h5" --threads 2; then
  if [ "$($PY -c 'import h5py,sys; print(h5py.File(sys.argv[1])["meta/threads"][()])' "$tmp/big2.h5")" = 2 ]; then
    check threads_1_vs_2_bit_identical $CHECK identical "$tmp/big1.h5" "$tmp/big2.h5"
  else ko threads_1_vs_2_bit_identical "the 2-thread run did not record 2 threads"; fi
else ko threads_1_vs_2_bit_identical "run failed"; fi

# ------------------------------------------------------------------ e. interrupted and resumed
# The same ring, longer: SIGTERM after a checkpoint, resumed on the other thread count.
R="--set time.duration_s=150 --set output.trajectory_interval_s=10"
if run "$tmp/big.yaml" -o "$tmp/ref.h5" $R --threads 1; then
  $BIN run "$tmp/big.yaml" -q -o "$tmp/res.h5" $R --threads 2 --checkpoint-every 0.1 2>/dev/null & pid=$!
  pids+=("$pid")
  if wait_checkpoint "$tmp/res.h5" $pid && signal_running TERM $pid; then
    wait $pid; rc=$?
    if [ $rc -eq 3 ] && $BIN run --resume "$tmp/res.h5" -q --threads 1; then
      check resume_with_lane_changes_bit_identical $CHECK identical "$tmp/ref.h5" "$tmp/res.h5"
    else ko resume_with_lane_changes_bit_identical "interrupted run exit $rc (want 3), or the resume failed"; fi
  else wait $pid; ko resume_with_lane_changes_bit_identical "the run ended before a checkpoint"; fi
else ko resume_with_lane_changes_bit_identical "reference run failed"; fi

# ------------------------------------------------------------------ f. physical sanity, every step
# Trajectories every step (the interval equals dt): the ring of b, shortened, plus a 3-lane variant.
two_lane "$tmp/every.yaml" symmetric 60 "45, 15" 3000 120 0.1
if run "$tmp/every.yaml" -o "$tmp/every.h5"; then check physical_two_lanes_every_step $CHECK physical "$tmp/every.h5" 10
else ko physical_two_lanes_every_step "run failed"; fi
# A lane empty at the start fills from the other: its newcomers take the lap of the first one's position, so some
# changes move x by a whole lap (lanes_check.py counts them; distance must not see them).
two_lane "$tmp/empty.yaml" symmetric 60 "60, 0" 3000 200 0.1
if run "$tmp/empty.yaml" -o "$tmp/empty.h5"; then check physical_empty_lane_fills $CHECK physical "$tmp/empty.h5" 10
else ko physical_empty_lane_fills "run failed"; fi
# The big ring's mix on 1500 m with 90 vehicles (50, 25, 15).
sed -e 's/vehicles: 13000/vehicles: 90/' -e 's/lane_counts: .*/lane_counts: [50, 25, 15]/' \
    -e 's/length_m: 200000/length_m: 1500/' "$tmp/big.yaml" >"$tmp/every3.yaml"
if run "$tmp/every3.yaml" -o "$tmp/every3.h5" --set output.trajectory_interval_s=0.1 --set time.duration_s=120; then
  check physical_three_lanes_every_step $CHECK physical "$tmp/every3.h5" 10,20
else ko physical_three_lanes_every_step "run failed"; fi

# ------------------------------------------------------------------ h. every decision against MOBIL recomputed
# All-IDM rings with the default IDM and MOBIL parameters, frames every step: lanes_check.py recomputes every
# step's changes from the frames (its own IDM and MOBIL, the engine's documented protocol) and they must agree.
if [ -f "$tmp/empty.h5" ]; then check mobil_replay_symmetric_empty_lane $CHECK mobil_replay "$tmp/empty.h5" symmetric
else ko mobil_replay_symmetric_empty_lane "no result"; fi
cat >"$tmp/idm3.yaml" <<EOF
name: idm3
seed: 9
road: {length_m: 1200, lanes: 3}
time: {duration_s: 120, dt_s: 0.1, output_interval_s: 1.0}
fleet:
  vehicles: 60
  lane_counts: [30, 20, 10]
  classes:
    - {class: midsize_sedan, fraction: 0.7}
    - {class: class8_tractor, fraction: 0.3}
  drivers:
    - {model: idm, fraction: 1.0, noise_mps2: 0.5}
output: {trajectories: true, trajectory_interval_s: 0.1}
EOF
if run "$tmp/idm3.yaml" -o "$tmp/idm3.h5"; then
  check mobil_replay_symmetric_three_lanes $CHECK mobil_replay "$tmp/idm3.h5" symmetric
else ko mobil_replay_symmetric_three_lanes "run failed"; fi
two_lane "$tmp/krE.yaml" keep_right 24 "11, 13" 3000 300 0.1 2
if run "$tmp/krE.yaml" -o "$tmp/krE.h5"; then
  check mobil_replay_keep_right $CHECK mobil_replay "$tmp/krE.h5" keep_right
  # the same changes do not follow the symmetric rule: the replay tells the rules apart
  if $CHECK mobil_replay "$tmp/krE.h5" symmetric >/dev/null 2>&1; then
    ko mobil_replay_tells_rules_apart "keep_right changes also pass as symmetric"
  else ok mobil_replay_tells_rules_apart; fi
else ko mobil_replay_keep_right "run failed"; fi

# ------------------------------------------------------------------ g. refusals
S=$tmp/sym.yaml
bad() { # name, expected text, scenario, --set assignments...
  local name=$1 want=$2 s=$3 msg rc; shift 3
  local sets=()
  for a in "$@"; do sets+=(--set "$a"); done
  msg=$($BIN run "$s" -q -o "$tmp/bad.h5" "${sets[@]}" 2>&1); rc=$?
  if [ $rc -eq 2 ] && printf '%s' "$msg" | grep -qF -- "$want" && [ ! -e "$tmp/bad.h5" ] &&
     [ ! -e "$tmp/bad.h5.partial" ]; then ok "$name"; else ko "$name" "rc=$rc $msg"; fi
}
bad lanes_zero "road.lanes" "$S" road.lanes=0
bad lanes_nine "road.lanes" "$S" road.lanes=9
sed 's/lane_counts: .*/lane_counts: [30, 20, 10]/' "$S" >"$tmp/lc_len.yaml"
bad lane_counts_wrong_length "fleet.lane_counts" "$tmp/lc_len.yaml"
sed 's/lane_counts: .*/lane_counts: [45, 14]/' "$S" >"$tmp/lc_sum.yaml"
bad lane_counts_wrong_sum "fleet.lane_counts" "$tmp/lc_sum.yaml"
sed 's/lane_counts: .*/lane_counts: [44.5, 15.5]/' "$S" >"$tmp/lc_frac.yaml"
bad lane_counts_not_integer "lane_counts" "$tmp/lc_frac.yaml"
bad lane_change_model_unknown "lane_change" "$S" "fleet.drivers[0].lane_change.model=lmrs"
# a corridor of several lanes takes its lanes' shares of the demand: one per lane, summing to 1
sed 's/^  inflow: {flow_vph: 1500,/  inflow: {lane_shares: [0.7, 0.2], flow_vph: 1500,/' tests/data/tiny_corridor.yaml >"$tmp/shares_sum.yaml"
bad corridor_lane_shares_sum "corridor.inflow.lane_shares" "$tmp/shares_sum.yaml" road.lanes=2
bad corridor_lane_shares_length "corridor.inflow.lane_shares" "$tmp/shares_sum.yaml" road.lanes=3
# an on-ramp and lane drops: the ramp inside the road, a lane that exists, some lane reaching the exit
B=scenarios/corridor_bottleneck_lanes.yaml
bad ramp_outside_road "corridor.on_ramp" "$B" corridor.on_ramp.end_m=7000
bad ramp_backwards "corridor.on_ramp" "$B" corridor.on_ramp.start_m=2400
bad ramp_too_many_lanes "corridor.on_ramp" "$B" road.lanes=8
bad drop_lane_out_of_range "corridor.lane_drops" "$B" "corridor.lane_drops[0].lane=4"
bad drop_merge_lane "corridor.lane_drops" "$B" "corridor.lane_drops[0].lane=0"
bad drop_outside_road "corridor.lane_drops" "$B" "corridor.lane_drops[0].at_m=6500"
sed 's/^  lane_drops: .*/  lane_drops: [{lane: 1, at_m: 4000}, {lane: 2, at_m: 4500}, {lane: 3, at_m: 5000}]/' "$B" >"$tmp/no_lane.yaml"
bad drop_leaves_no_lane "every lane ends before the exit" "$tmp/no_lane.yaml"
bad cvode_with_lanes "time.integrator" "$S" time.integrator=cvode
