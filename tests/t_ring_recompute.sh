#!/usr/bin/env bash
# A ring's observer columns (/timeseries, /vehicles, /summary, per class) against an independent recomputation in
# numpy from trajectories written every step (tests/recompute/ring.py states the definitions and tolerances). 600
# vehicles (three 256-vehicle statistics blocks, the last partial) of two classes start at rest; human drivers (IDM,
# noise, heterogeneity) and two scripted vehicles (examples/plugins/scripted_accel.c) at positions 0 and 256 that
# stand for 25 s, then drive off: slow runs sit across the ring's end (599/0) and a block boundary (255/256) while
# the queues behind them grow, brake and stop. The same scenario without trajectories (the fused step) must give
# the same recomputed values.
set -u
BUILD=${BUILD:-build}
SO="$(pwd)/$BUILD/plugins/scripted_accel.so"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
if [ ! -f "$SO" ]; then echo "FAIL ring_recompute_plugin: $SO missing: run make tests"; exit 1; fi
cat >"$tmp/ring.yaml" <<EOF
name: ring_recompute
seed: 11
road: {length_m: 12000}
time: {duration_s: 60, dt_s: 0.1, output_interval_s: 0.2, warmup_s: 10}
fleet:
  vehicles: 600
  placement: random
  classes:
    - {class: midsize_sedan, fraction: 0.7}
    - {class: class8_tractor, fraction: 0.3, length_m: 12}
  drivers:
    - {name: blockers, model: plugin, path: $SO, placement: explicit, indices: [0, 256],
       params: {a1_mps2: 1, n1_steps: 100, a2_mps2: -5, n2_steps: 20, n3_steps: 100, a4_mps2: 1, n4_steps: 100}}
    - name: humans
      model: idm
      count: 598
      noise_mps2: 0.4
      params: {v0_mps: 25, T_s: 1.2}
      heterogeneity: {spread: {T_s: 0.2, a_mps2: 0.2}}
initial: {state: rest}
statistics: {v_stop_mps: 0.5, v_go_mps: 2.0, hard_brake_mps2: 1.0, wave_speed_mps: 3.0}
output: {trajectories: true, trajectory_interval_s: 0.1}
EOF
bash tests/recompute/run_pair.sh ring_recompute "$tmp/ring.yaml" tests/recompute/ring.py "$tmp"
