#!/usr/bin/env bash
# A corridor's observer columns (/timeseries, /trips, /detectors, /edie, /summary) against an independent
# recomputation in numpy from trajectory points written every step (tests/recompute/corridor.py states the
# definitions and tolerances): two classes, IDM drivers with noise and heterogeneity, Poisson demand above the
# capacity of a slow zone for 150 s and then none, so a queue forms on the road and at the entrance and drains; Edie
# cells and detector intervals whose last ones are shorter; a detector 1 m before the exit (passages in exit steps).
# The same scenario without trajectories must give the same recomputed values.
set -u
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cat >"$tmp/corridor.yaml" <<EOF
name: corridor_recompute
seed: 5
road:
  type: corridor
  length_m: 2050
  speed_limit_mps: 30
  zones:
    - {type: speed_limit, from_m: 1400, to_m: 1420, speed_limit_mps: 1}
time: {duration_s: 290, dt_s: 0.1, output_interval_s: 0.5, warmup_s: 30}
fleet:
  classes:
    - {class: midsize_sedan, fraction: 0.8}
    - {class: class8_tractor, fraction: 0.2}
  drivers:
    - {model: idm, fraction: 1.0, noise_mps2: 0.3, heterogeneity: {spread: {T_s: 0.2}}}
corridor:
  inflow: {points: [[0, 1800], [150, 1800], [150.5, 0]], arrivals: poisson}
  detectors: {x_m: [300, 1450, 2049], interval_s: 40}
  edie: {dx_m: 100, dt_s: 30}
output: {trajectories: true, trajectory_interval_s: 0.1}
EOF
bash tests/recompute/run_pair.sh corridor_recompute "$tmp/corridor.yaml" tests/recompute/corridor.py "$tmp"
# The same corridor with drivers whose noise outruns their braking limit: overlap repairs (each predicted here from
# the ballistic step and the leader's new position) in /timeseries/overlaps and /summary/overlaps.
mkdir -p "$tmp/overlaps"
sed -e 's/noise_mps2: 0.3,/noise_mps2: 1.5, decel_max_mps2: 2.5,/' "$tmp/corridor.yaml" >"$tmp/overlaps/corridor.yaml"
if grep -q 'decel_max_mps2: 2.5' "$tmp/overlaps/corridor.yaml" &&
   "${WAVEFUEL_BIN:-bin/wavefuel}" run "$tmp/overlaps/corridor.yaml" -q -o "$tmp/overlaps/traj.h5"; then
  RECOMPUTE_NAME=corridor_overlaps /usr/bin/python3 tests/recompute/corridor.py "${WAVEFUEL_BIN:-bin/wavefuel}" \
    "$tmp/overlaps/traj.h5" "$tmp/overlaps"
  if /usr/bin/python3 -c 'import h5py, sys; sys.exit(int(h5py.File(sys.argv[1])["summary/overlaps"][()] < 10))' \
       "$tmp/overlaps/traj.h5"; then echo "PASS corridor_overlaps_occur"
  else echo "FAIL corridor_overlaps_occur: fewer than 10 overlap repairs"; fi
else
  echo "FAIL corridor_overlaps_runs"
fi
