#!/usr/bin/env bash
# Units against the docs: every dataset of a ring result (with trajectories), a ring result of a SUNDIALS integrator
# (/solver), multi-lane ring and corridor results (/lanes and their per-vehicle columns) and a corridor result (trips, detectors, Edie, trajectories) must be listed in docs/output.md's tables
# ("Every dataset", "Every dataset of a corridor result", "/solver") with exactly the `units` attribute the file
# has (exact string: `g` is not `kg`), and every row of those tables must exist in the file of its kind. A sweep
# table's /metrics/NAME and /class_metrics/NAME carry the units of /summary/NAME (docs/sweeps.md: "as in a run file").
# Not compared: /classes/params/NAME/KEY (every energy-model coefficient of every class; output.md says they are
# not listed there).
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
PY=/usr/bin/python3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
run() { "$BIN" run "$@" -q --force 2>&1; }
# The ring and corridor runs have a safety filter, so the /summary datasets of filtered runs are in their files.
SF="--set fleet.drivers[0].safety.kind=ttc"
if ! run tests/data/tiny_ring.yaml -o "$tmp/ring.h5" --set time.duration_s=6 $SF ||
   ! run tests/data/tiny_ring.yaml -o "$tmp/cvode.h5" --set time.duration_s=1 --set time.warmup_s=0 --set time.integrator=cvode ||
   ! run tests/data/tiny_corridor.yaml -o "$tmp/corridor.h5" --set time.duration_s=60 $SF ||
   ! run scenarios/ring_lanes.yaml -o "$tmp/lanes.h5" --set time.duration_s=20 --set time.warmup_s=5 $SF ||
   ! run scenarios/corridor_bottleneck_lanes.yaml -o "$tmp/clanes.h5" --set time.duration_s=120 --set time.warmup_s=10 $SF \
       --set corridor.off_ramp.at_m=3000 --set corridor.off_ramp.share=0.2; then
  echo "FAIL units_runs"; exit 1
fi
cat >"$tmp/sweep.yaml" <<EOF
scenario: $PWD/tests/data/tiny_ring.yaml
set: {time.duration_s: 6, output.trajectories: false}
axes:
  - key: fleet.drivers[0].noise_mps2
    values: [0.1, 0.2]
EOF
if ! "$BIN" sweep "$tmp/sweep.yaml" -o "$tmp/sweep.h5" --threads 1 -q >/dev/null 2>&1; then
  echo "FAIL units_sweep_run"; exit 1
fi
$PY - "$tmp" docs/output.md <<'PY'
import re, sys, h5py
tmp, doc = sys.argv[1], open(sys.argv[2]).read()

def table(heading):
    """{dataset: units} of the markdown table under `heading` (rows that name several datasets, as in the /solver
    table, give either one unit for all or one unit each)."""
    part = doc.split("\n## " + heading + "\n", 1)
    assert len(part) == 2, "docs/output.md has no section " + heading
    rows = {}
    for line in part[1].split("\n## ", 1)[0].splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 2 or not cells[0].startswith("`"):
            continue
        names = ["/" + n.strip("/") for n in re.findall(r"`([^`]+)`", cells[0])]
        units = [u.strip() for u in cells[1].split(",")] if len(names) > 1 else [cells[1]]
        if len(units) == 1: units *= len(names)
        assert len(units) == len(names), line
        rows.update(zip(names, units))
    return rows

def datasets(path):
    out = {}
    def visit(name, obj):
        if isinstance(obj, h5py.Dataset) and not name.startswith("classes/params/"):
            u = obj.attrs.get("units")
            # one row of the docs stands for every lane's Edie group (/lanes/edie/laneL/...)
            out["/" + re.sub(r"^lanes/edie/lane[0-9]+/", "lanes/edie/laneL/", name)] = u.decode() if isinstance(u, bytes) else u
    h5py.File(path).visititems(visit)
    return out

ring, corridor, solver = table("Every dataset"), table("Every dataset of a corridor result"), table("`/solver` (SUNDIALS integrators only)")
failed = False
def compare(name, have, docs, must_have_all):
    global failed
    bad = [f"{d}: file '{u}', docs '{docs[d]}'" for d, u in sorted(have.items()) if d in docs and docs[d] != u]
    bad += [f"{d}: units '{u}' in the file, not in the docs" for d, u in sorted(have.items()) if d not in docs]
    if must_have_all:
        bad += [f"{d}: in the docs, not in the file" for d in sorted(docs) if d not in have]
    if len(have) < 20: bad.append(f"only {len(have)} datasets")
    print(("FAIL " if bad else "PASS ") + name + (": " + "; ".join(bad[:8]) if bad else ""))
    failed |= bool(bad)

compare("units_ring_vs_docs", datasets(tmp + "/ring.h5"), ring, True)
cv = datasets(tmp + "/cvode.h5")
compare("units_ring_solver_vs_docs", cv, {**ring, **solver}, False)
missing = [d for d in solver if d not in cv]
print(("FAIL" if missing else "PASS") + " units_solver_table_exists" + (": " + ", ".join(missing) if missing else ""))
compare("units_corridor_vs_docs", datasets(tmp + "/corridor.h5"), corridor, True)
lanes = table("Every dataset a multi-lane ring adds")
# (its FollowerStopper group adds param_KEY datasets the ring table does not list: they depend on the models used)
compare("units_lanes_vs_docs", {d: u for d, u in datasets(tmp + "/lanes.h5").items()
                                if d in ring or not d.startswith("/vehicles/param_")}, {**ring, **lanes}, False)
missing = [d for d in lanes if d not in datasets(tmp + "/lanes.h5")]
print(("FAIL" if missing else "PASS") + " units_lanes_table_exists" + (": " + ", ".join(missing) if missing else ""))
clanes = table("Every dataset a multi-lane corridor adds")
lane_sets = {d: u for d, u in lanes.items() if d.startswith(("/lanes/", "/summary/"))}
compare("units_corridor_lanes_vs_docs", datasets(tmp + "/clanes.h5"), {**corridor, **lane_sets, **clanes}, False)
missing = [d for d in {**lane_sets, **clanes} if d not in datasets(tmp + "/clanes.h5")]
print(("FAIL" if missing else "PASS") + " units_corridor_lanes_table_exists" + (": " + ", ".join(missing) if missing else ""))
sw = datasets(tmp + "/sweep.h5")
want = {d: ring.get("/summary/" + d.split("/")[-1]) for d in sw if d.startswith(("/metrics/", "/class_metrics/"))}
want["/class_metrics/class_count"] = "1"  # a sweep-only column: vehicles of the class
compare("units_sweep_metrics_vs_docs", {d: sw[d] for d in want}, want, True)
PY
