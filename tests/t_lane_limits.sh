#!/usr/bin/env bash
# Speed limits and zones per lane on corridors (road.lane_speed_limits_mps, road.zones[i].lanes; docs/lanes.md):
# a. with lane changes off, each lane of a two-lane corridor equals, bit for bit (every trip's times, speeds and fuel),
#    the single-lane corridor of its share of the demand driven with that lane's limit and zones (deterministic
#    arrivals, one class, one group, no noise, so lane 1 equals it too, serials 2^40 + n): lane 0 under a 22 m/s
#    limit and a headway zone, lane 1 under the road's 31 m/s and a 12 m/s zone that lane 0 does not have;
# b. the limits bind where they should, from trajectories written every step: lane 0 never above 22 m/s and at it,
#    lane 1 inside its zone never above 12 m/s, lane 0 there still at 22 m/s;
# c. with an on-ramp the merge lane is lane 0 of the list and of the zones' lanes;
# d. refusals (exit 2, the key named, no file): a list of the wrong length (also counting the merge lane), a zone's
#    lane out of range, twice, or not a whole number, an empty list.
set -u
cd "$(dirname "$0")/.." || exit 1
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
PY=/usr/bin/python3
. tests/scaffold.sh

SPEED_ZONE="    - {type: speed_limit, from_m: 1500, to_m: 2500, speed_limit_mps: 12"
HEADWAY_ZONE="    - {type: headway, from_m: 3000, to_m: 3500, factor: 2.0"
# scenario LANES LIMITS ZONE0_LANES ZONE1_LANES FLOW [EXTRA_CORRIDOR_LINE]: both zones, each on the lanes given
# (", lanes: [...]", or "" for every lane, or "none" to leave the zone out)
zone() { [ "$2" = none ] || echo "$1$2}"; }
scenario() {
  cat <<EOF
name: lane_limits
seed: 5
road:
  type: corridor
  length_m: 4000
  lanes: $1
  speed_limit_mps: 31
$2
  zones:
$(zone "$SPEED_ZONE" "$3")
$(zone "$HEADWAY_ZONE" "$4")
time: {duration_s: 600, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 0}
fleet:
  placement: random
  classes: [{class: midsize_sedan, fraction: 1.0, length_m: 4.9}]
  drivers:
    - {name: h, model: idm, fraction: 1.0, params: {v0_mps: 30, T_s: 1.2, s0_m: 2.0, a_mps2: 1.0, b_mps2: 1.5, delta: 4},
       lane_change: {model: none}}
corridor:
  inflow: {flow_vph: $5, arrivals: deterministic}
  outflow: {type: free}
$6
output: {trajectories: true, trajectory_interval_s: 0.1}
EOF
}

scenario 2 "  lane_speed_limits_mps: [22, 31]" ", lanes: [1]" ", lanes: [0]" 1200 "" >"$tmp/two.yaml"
# each lane alone: lane 0 with its limit 22 and its headway zone, lane 1 with the road's limit and its speed zone
scenario 1 "  lane_speed_limits_mps: [22]" none "" 600 "" >"$tmp/lane0.yaml"
scenario 1 "" "" none 600 "" >"$tmp/lane1.yaml"
for s in two lane0 lane1; do
  if ! "$BIN" run "$tmp/$s.yaml" -o "$tmp/$s.h5" -q --threads 1 >"$tmp/$s.log" 2>&1; then
    ko "run_$s" "$(cat "$tmp/$s.log")"
  fi
done


check lanes_equal_single_lane_roads $PY - "$tmp" <<'EOF'
import sys, h5py, numpy as np
d = sys.argv[1]
def trips(path):
    with h5py.File(path) as f:
        return {k: f["trips"][k][:] for k in f["trips"]}
two, n_checked = trips(f"{d}/two.h5"), 0
for lane, single in ((0, "lane0"), (1, "lane1")):
    one = trips(f"{d}/{single}.h5")
    m = two["lane"] == lane
    ser = two["serial"][m] - lane * 2**40
    o2, o1 = np.argsort(ser), np.argsort(one["serial"])
    if not np.array_equal(ser[o2], one["serial"][o1]):
        sys.exit(f"lane {lane}: serials differ from {single}")
    for k in ("entry_time", "exit_time", "entry_speed", "fuel", "travel_time", "distance", "stops"):
        a, b = two[k][m][o2], one[k][o1]
        if not np.array_equal(a, b, equal_nan=True):
            i = np.flatnonzero(~((a == b) | (np.isnan(a) & np.isnan(b))))[0]
            sys.exit(f"lane {lane} /trips/{k}[{i}]: {a[i]!r} against {b[i]!r} on its own road")
    n_checked += int(m.sum())
print(f"{n_checked} trips of both lanes equal their single-lane corridors bit for bit")
EOF

check limits_bind $PY - "$tmp/two.h5" <<'EOF'
import sys, h5py, numpy as np
with h5py.File(sys.argv[1]) as f:
    t = f["trajectories"]; x, v, l = t["x"][:], t["v"][:], t["lane"][:]
def vmax(lane, a, b):
    m = (l == lane) & (x >= a) & (x < b)
    return v[m].max()
# the zone's limit is met from its start: 1520 m leaves a car length for braking into it
got = dict(l0=vmax(0, 0, 4000), l1_zone=vmax(1, 1520, 2500), l0_zone=vmax(0, 1520, 2500), l1_out=vmax(1, 2700, 4000))
if not (got["l0"] <= 22.0 + 1e-12 and got["l0"] > 21.9): sys.exit(f"lane 0's 22 m/s limit: max {got['l0']!r}")
if not (got["l1_zone"] <= 12.0 + 1e-12): sys.exit(f"lane 1's 12 m/s zone: max {got['l1_zone']!r}")
if not got["l0_zone"] > 21.9: sys.exit(f"lane 0 slowed by lane 1's zone: max {got['l0_zone']!r}")
if not got["l1_out"] > 25.0: sys.exit(f"lane 1 beyond its zone: max {got['l1_out']!r}")
print(", ".join(f"{k} max {q:.4f} m/s" for k, q in got.items()))
EOF

# c. an on-ramp: its merge lane is lane 0 of the list (10 m/s there) and of the zones
scenario 2 "  lane_speed_limits_mps: [10, 22, 31]" ", lanes: [2]" ", lanes: [1]" 1200 \
  "  on_ramp: {start_m: 1000, end_m: 1400, flow_vph: 300}" >"$tmp/ramp.yaml"
if "$BIN" run "$tmp/ramp.yaml" -o "$tmp/ramp.h5" -q --threads 1 >"$tmp/ramp.log" 2>&1; then
  check ramp_lane_numbering $PY - "$tmp/ramp.h5" <<'EOF'
import sys, h5py, numpy as np
with h5py.File(sys.argv[1]) as f:
    t = f["trajectories"]; x, v, l = t["x"][:], t["v"][:], t["lane"][:]
m0, m1, m2z = l == 0, l == 1, (l == 2) & (x >= 1520) & (x < 2500)
got = (v[m0].max(), v[m1].max(), v[m2z].max())
if not (got[0] <= 10 + 1e-12 and m0.any()): sys.exit(f"merge lane above its 10 m/s: {got[0]!r}")
if not (got[1] <= 22 + 1e-12 and got[1] > 21.9): sys.exit(f"lane 1 against its 22 m/s: {got[1]!r}")
if not (got[2] <= 12 + 1e-12): sys.exit(f"lane 2's zone: {got[2]!r}")
print(f"merge lane max {got[0]:.3f}, lane 1 max {got[1]:.3f}, lane 2 in its zone max {got[2]:.3f} m/s")
EOF
else
  ko ramp_lane_numbering "$(cat "$tmp/ramp.log")"
fi

# d. refusals
refuse() {
  local name=$1 want=$2 f="$tmp/bad_$1.yaml"
  cat >"$f"
  "$BIN" run "$f" -o "$tmp/bad_$name.h5" -q >"$tmp/bad.log" 2>&1
  local rc=$?
  if [ $rc -eq 2 ] && grep -q -- "$want" "$tmp/bad.log" && [ ! -e "$tmp/bad_$name.h5" ]; then
    ok "refuse_$name ($(head -c 200 "$tmp/bad.log"))"
  else
    ko "refuse_$name" "exit $rc, want 2 naming '$want', no file: $(cat "$tmp/bad.log")"
  fi
}
scenario 2 "  lane_speed_limits_mps: [22]" "" "" 1200 "" | refuse limits_count "road.lane_speed_limits_mps lists 1 lanes but the corridor has 2"
scenario 2 "  lane_speed_limits_mps: [22, 31]" "" "" 1200 "  on_ramp: {start_m: 1000, end_m: 1400, flow_vph: 300}" |
  refuse limits_count_ramp "on-ramp's merge lane 0"
scenario 2 "" ", lanes: [2]" "" 1200 "" | refuse zone_lane_range "road.zones\[0\].lanes: the road has lanes 0 to 1"
scenario 2 "" ", lanes: [1, 1]" "" 1200 "" | refuse zone_lane_twice "road.zones\[i\].lanes: expected whole lane numbers, each once"
scenario 2 "" ", lanes: [0.5]" "" 1200 "" | refuse zone_lane_fraction "expected whole lane numbers"
scenario 2 "" ", lanes: []" "" 1200 "" | refuse zone_lanes_empty "expected at least one lane"
