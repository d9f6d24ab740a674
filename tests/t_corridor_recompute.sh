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
# Ten classes (the six shipped ones and four copies under other names in $WAVEFUEL_VEHICLES, with other lengths): the
# class profiles (/edie/class_*) of more than eight classes, where the measurement holds classes in four vectors.
mkdir -p "$tmp/classes/vehicles"
cp vehicles/*.yaml "$tmp/classes/vehicles/"
for k in 1 2 3 4; do
  sed -e "s/^name: .*/name: Copy $k/" vehicles/midsize_sedan.yaml >"$tmp/classes/vehicles/copy$k.yaml"
done
/usr/bin/python3 - "$tmp/corridor.yaml" "$tmp/classes/corridor.yaml" <<'PY'
import sys
src = open(sys.argv[1]).read()
old = """    - {class: midsize_sedan, fraction: 0.8}
    - {class: class8_tractor, fraction: 0.2}
"""
names = ["compact_sedan", "midsize_sedan", "midsize_suv", "midsize_pickup", "class4_pnd", "class8_tractor",
         "copy1", "copy2", "copy3", "copy4"]
new = "".join("    - {class: %s, fraction: 0.1, length_m: %g}\n" % (n, 4.0 + 0.25 * k) for k, n in enumerate(names))
assert old in src
open(sys.argv[2], "w").write(src.replace(old, new))
PY
RECOMPUTE_NAME=corridor_ten_classes WAVEFUEL_VEHICLES="$tmp/classes/vehicles" bash tests/recompute/run_pair.sh corridor_recompute_ten_classes \
  "$tmp/classes/corridor.yaml" tests/recompute/corridor.py "$tmp/classes"
