#!/usr/bin/python3
"""SUMO's side of the issue 18 comparison ("Lanes"): the three-lane corridor with an on-ramp and a lane drop, built
from plain XML with netconvert, run with sumo (no GUI), and measured as bench/lanes_sumo/run.py compares it with
wavefuel (corridor.yaml).

Geometry (x from the entrance, m; lane 0 the rightmost, as in SUMO and wavefuel):

    edge    from   to     lanes  SUMO lanes                           wavefuel lanes (with an on-ramp)
    up         0  2000    3      0, 1, 2 main                         1, 2, 3
    merge   2000  2300    4      0 the merge lane, 1, 2, 3 main       0 the merge lane, 1, 2, 3
    mid     2300  4500    3      0, 1, 2 main                         1, 2, 3
    down    4500  6000    2      0, 1                                 1, 2 (3 ended at 4500)

The connections are written explicitly (tools' .con.xml), lane by lane: up 0/1/2 -> merge 1/2/3; merge 1/2/3 ->
mid 0/1/2 (merge lane 0 has no successor: it ends at 2300 and its vehicles must change to lane 1 before); mid 0/1
-> down 0/1 (mid lane 2, the leftmost, has no successor: it ends at 4500). Every edge's length is set and the net
is built without internal links (--no-internal-links), so the road is exactly 6000 m long and a vehicle passes a
node without a junction's internal lane; lane changes happen on the edges only (as on wavefuel's road, whose lanes
change count at points). check_net() reads the built net back and verifies lane counts, lengths and connections.

Demand: one flow per main lane on `up` (departLane 0, 1, 2), 4200/3 veh/h each, and one ramp flow of 700 veh/h
departing on lane 0 of `merge` at its start (the ramp vehicles enter the merge lane at x = 2000 m, as in
wavefuel); every flow Poisson: `period="exp(q/3600)"` (exponential headways of rate q/3600 1/s; accepted by SUMO
1.15, the loaded counts match the demand), the flows' draws seeded by --seed. departSpeed "last" by default (the
speed of the last vehicle on the lane: the nearest to wavefuel's rule, which inserts at the leader's speed;
--depart-speed max: the highest speed SUMO deems safe, which at this demand collapses to 0 m/s at the entrance, see
README.md), departPos "base" (the vehicle's rear at the start of the lane), --eager-insert (each lane's
flow is tried on its own every step: a blocked lane does not hold back the others, as wavefuel's per-lane
queues). Vehicles that cannot be inserted wait (--max-depart-delay -1): the insertion backlog, read from the
summary output's "waiting" at the last step.

Drivers: one vType, IDM (v0 = maxSpeed 30 m/s, speedFactor 1 without deviation, T = tau 1.2 s, s0 = minGap 2 m,
a = accel 1.0, b = decel 1.5, delta 4, emergencyDecel 9, sigma 0: SUMO's IDM has no noise), length 4.9 m,
laneChangeModel LC2013 with its defaults; speed limit 31 m/s on every lane; ballistic update, step 0.1 s;
--time-to-teleport -1 (no teleports, like wavefuel: a vehicle stuck at a lane end waits for a gap);
collisions only warned about and counted.

Measures (window: after the warm-up, to the end):
- throughput: vehicles leaving the road (tripinfo arrival) in the window, per hour;
- mean travel time of the completed trips that were inserted after the warm-up, main and ramp vehicles apart and
  together (tripinfo duration = arrival - insertion; for ramp vehicles from x = 2000 m), and the mean insertion
  delay (tripinfo departDelay);
- the insertion backlog at the end (vehicles loaded but not yet inserted), lane changes (tripinfo has none:
  counted with --lanechange-output), collisions, teleports.
Usage: /usr/bin/python3 bench/lanes_sumo/sumo_corridor.py [--seed 1] [--keep DIR] [--json] [--depart-speed last]
                                                         [--lc-params 'lcCooperative="0"'] [--main-vph 4200]
                                                         [--ramp-vph 700]"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET

SCEN = dict(
    length_m=6000.0, lanes=3, speed_limit_mps=31.0,
    ramp_from_m=2000.0, ramp_to_m=2300.0, drop_at_m=4500.0,
    main_vph=4200.0, ramp_vph=700.0,
    duration_s=3600.0, warmup_s=600.0, dt_s=0.1,
    depart_speed="last", lc_params="",
    car_m=4.9, v0=30.0, T=1.2, s0=2.0, a=1.0, b=1.5, delta=4.0, emergency_decel=9.0,
)
EDGES = (  # id, from x, to x, lanes
    ("up", 0.0, 2000.0, 3),
    ("merge", 2000.0, 2300.0, 4),
    ("mid", 2300.0, 4500.0, 3),
    ("down", 4500.0, 6000.0, 2),
)
CONNECTIONS = (  # from edge, from lane, to edge, to lane
    ("up", 0, "merge", 1), ("up", 1, "merge", 2), ("up", 2, "merge", 3),
    ("merge", 1, "mid", 0), ("merge", 2, "mid", 1), ("merge", 3, "mid", 2),
    ("mid", 0, "down", 0), ("mid", 1, "down", 1),
)


def available():
    if not (shutil.which("sumo") and shutil.which("netconvert")):
        return "sumo / netconvert not on PATH (Debian: bash tools/install-deps.sh sumo)"
    return None


def sumo_version():
    out = subprocess.run(["sumo", "--version"], capture_output=True, text=True).stdout
    return out.splitlines()[0].strip() if out else "?"


def write_net(d, sc=SCEN):
    """Nodes, edges and connections as plain XML in d, netconvert to corridor.net.xml; returns netconvert's
    messages (warnings about the dead-end lanes are expected: they are the lane ends)."""
    xs = sorted({e[1] for e in EDGES} | {e[2] for e in EDGES})
    with open(os.path.join(d, "corridor.nod.xml"), "w") as f:
        f.write("<nodes>\n" + "".join(f'  <node id="n{int(x)}" x="{x:.2f}" y="0.00" type="priority"/>\n'
                                      for x in xs) + "</nodes>\n")
    with open(os.path.join(d, "corridor.edg.xml"), "w") as f:
        f.write("<edges>\n" + "".join(
            f'  <edge id="{e}" from="n{int(x0)}" to="n{int(x1)}" numLanes="{n}" speed="{sc["speed_limit_mps"]!r}" '
            f'length="{x1 - x0:.2f}" priority="1"/>\n' for e, x0, x1, n in EDGES) + "</edges>\n")
    with open(os.path.join(d, "corridor.con.xml"), "w") as f:
        f.write("<connections>\n" + "".join(
            f'  <connection from="{a}" to="{b}" fromLane="{i}" toLane="{j}"/>\n' for a, i, b, j in CONNECTIONS)
            + "</connections>\n")
    r = subprocess.run(["netconvert", "--xml-validation", "never", "-n", "corridor.nod.xml", "-e", "corridor.edg.xml",
                        "-x", "corridor.con.xml", "-o", "corridor.net.xml", "--no-internal-links",
                        "--no-turnarounds", "--offset.disable-normalization"],
                       cwd=d, capture_output=True, text=True, check=True)
    return (r.stdout + r.stderr).strip()


def check_net(d):
    """The built net's lanes per edge, lane lengths and lane-to-lane connections, checked against EDGES and
    CONNECTIONS; returns a one-line description, raises when the geometry is not the intended one."""
    root = ET.parse(os.path.join(d, "corridor.net.xml")).getroot()
    lanes, lengths = {}, {}
    for e in root.iter("edge"):
        if e.get("function") == "internal":
            continue
        ls = e.findall("lane")
        lanes[e.get("id")] = len(ls)
        lengths[e.get("id")] = {float(l.get("length")) for l in ls}
    cons = sorted((c.get("from"), int(c.get("fromLane")), c.get("to"), int(c.get("toLane")))
                  for c in root.iter("connection") if not c.get("from", "").startswith(":"))
    want_lanes = {e: n for e, _, _, n in EDGES}
    want_len = {e: {x1 - x0} for e, x0, x1, _ in EDGES}
    if lanes != want_lanes or lengths != want_len or cons != sorted(CONNECTIONS):
        raise RuntimeError(f"net differs from the design: lanes {lanes}, lengths {lengths}, connections {cons}")
    return ("lanes per edge " + ", ".join(f"{e} {lanes[e]} ({min(lengths[e]):g} m)" for e, *_ in EDGES)
            + f"; {len(cons)} connections; dead ends: merge lane 0 at 2300 m, mid lane 2 at 4500 m")


def write_routes(d, sc=SCEN):
    per_lane = sc["main_vph"] / sc["lanes"]
    with open(os.path.join(d, "corridor.rou.xml"), "w") as f:
        f.write("<routes>\n")
        f.write(f'  <vType id="car" carFollowModel="IDM" accel="{sc["a"]!r}" decel="{sc["b"]!r}" '
                f'emergencyDecel="{sc["emergency_decel"]!r}" tau="{sc["T"]!r}" minGap="{sc["s0"]!r}" '
                f'delta="{sc["delta"]!r}" maxSpeed="{sc["v0"]!r}" length="{sc["car_m"]!r}" sigma="0" '
                'speedFactor="1" speedDev="0" laneChangeModel="LC2013"'
                + (" " + sc["lc_params"] if sc["lc_params"] else "") + '/>\n')
        f.write('  <route id="main" edges="up merge mid down"/>\n')
        f.write('  <route id="ramp" edges="merge mid down"/>\n')
        end = sc["duration_s"]
        for lane in range(sc["lanes"]):
            f.write(f'  <flow id="main{lane}" type="car" route="main" begin="0" end="{end!r}" '
                    f'period="exp({per_lane / 3600.0!r})" departLane="{lane}" departSpeed="{sc["depart_speed"]}" '
                    'departPos="base"/>\n')
        f.write(f'  <flow id="ramp" type="car" route="ramp" begin="0" end="{end!r}" '
                f'period="exp({sc["ramp_vph"] / 3600.0!r})" departLane="0" departSpeed="{sc["depart_speed"]}" '
                'departPos="base"/>\n')
        f.write("</routes>\n")


def run_sumo(d, seed, sc=SCEN):
    cmd = ["sumo", "--xml-validation", "never", "-n", "corridor.net.xml", "-r", "corridor.rou.xml",
           "--begin", "0", "--end", f"{sc['duration_s']!r}", "--step-length", f"{sc['dt_s']!r}",
           "--step-method.ballistic", "true", "--seed", str(seed), "--eager-insert", "true",
           "--max-depart-delay", "-1", "--time-to-teleport", "-1", "--collision.action", "warn",
           "--collision-output", "collisions.xml", "--tripinfo-output", "tripinfo.xml",
           "--summary-output", "summary.xml", "--lanechange-output", "lanechanges.xml",
           "--statistic-output", "stats.xml", "--no-step-log", "--duration-log.disable"]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, cwd=d, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(f"sumo exited with {r.returncode}:\n{r.stderr[-3000:]}")
    return wall, r.stderr


def measure(d, sc=SCEN):
    w0, t_end = sc["warmup_s"], sc["duration_s"]
    window_h = (t_end - w0) / 3600.0
    exits = 0
    tt = {"main": [], "ramp": []}
    delay = {"main": [], "ramp": []}
    inserted = {"main": 0, "ramp": 0}
    for _, el in ET.iterparse(os.path.join(d, "tripinfo.xml")):
        if el.tag != "tripinfo":
            continue
        arr, dep = float(el.get("arrival")), float(el.get("depart"))
        kind = "ramp" if el.get("id").startswith("ramp") else "main"
        if w0 <= arr <= t_end:
            exits += 1
        if dep >= w0:
            tt[kind].append(float(el.get("duration")))
            delay[kind].append(float(el.get("departDelay")))
        el.clear()
    last = None
    for _, el in ET.iterparse(os.path.join(d, "summary.xml")):
        if el.tag == "step":
            last = dict(el.attrib)
        el.clear()
    lc = {"total": 0, "strategic": 0, "cooperative": 0, "speedGain": 0, "keepRight": 0, "other": 0}
    for _, el in ET.iterparse(os.path.join(d, "lanechanges.xml")):
        if el.tag == "change":
            lc["total"] += 1
            reason = el.get("reason", "")
            key = next((k for k in ("strategic", "cooperative", "speedGain", "keepRight") if k in reason), "other")
            lc[key] += 1
        el.clear()
    with open(os.path.join(d, "collisions.xml")) as f:
        collisions = f.read().count("<collision ")
    stats = ET.parse(os.path.join(d, "stats.xml")).getroot()
    tele = stats.find("teleports")
    mean = lambda xs: sum(xs) / len(xs) if xs else float("nan")
    every = tt["main"] + tt["ramp"]
    return dict(
        throughput_vph=exits / window_h,
        exits_window=exits,
        tt_mean_s=mean(every), tt_main_s=mean(tt["main"]), tt_ramp_s=mean(tt["ramp"]),
        trips_main=len(tt["main"]), trips_ramp=len(tt["ramp"]),
        insert_delay_main_s=mean(delay["main"]), insert_delay_ramp_s=mean(delay["ramp"]),
        backlog_end=int(last["waiting"]), loaded=int(last["loaded"]), inserted_total=int(last["inserted"]),
        running_end=int(last["running"]), lane_changes=lc, collisions=collisions,
        teleports=int(tele.get("total")) if tele is not None else 0,
    )


def run(seed, keep=None, sc=SCEN):
    """One SUMO run of the corridor with `seed`: measure()'s dict plus wall time, the net check and versions."""
    d = keep or tempfile.mkdtemp(prefix="wf_lanes_sumo_")
    os.makedirs(d, exist_ok=True)
    try:
        net_msgs = write_net(d, sc)
        net = check_net(d)
        write_routes(d, sc)
        wall, log = run_sumo(d, seed, sc)
        res = measure(d, sc)
        res.update(seed=seed, wall_s=wall, net=net, netconvert_messages=net_msgs,
                   sumo_warnings=sum(1 for l in log.splitlines() if l.startswith("Warning")))
        return res
    finally:
        if keep is None:
            shutil.rmtree(d, ignore_errors=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--keep", help="directory for the net, routes and outputs (kept)")
    ap.add_argument("--json", action="store_true", help="print the result as JSON")
    ap.add_argument("--depart-speed", default=SCEN["depart_speed"],
                    help="SUMO's departSpeed of every flow (last, max, desired, avg, speedLimit, a number)")
    ap.add_argument("--lc-params", default="",
                    help='extra vType attributes, e.g. \'lcCooperative="0"\' (diagnostic: LC2013 without cooperation)')
    ap.add_argument("--main-vph", type=float, default=SCEN["main_vph"], help="main demand (veh/h, all lanes)")
    ap.add_argument("--ramp-vph", type=float, default=SCEN["ramp_vph"], help="ramp demand (veh/h)")
    a = ap.parse_args()
    why = available()
    if why:
        print(f"SUMO corridor: not run: {why}")
        return 1
    r = run(a.seed, a.keep, dict(SCEN, depart_speed=a.depart_speed, lc_params=a.lc_params, main_vph=a.main_vph,
                                 ramp_vph=a.ramp_vph))
    if a.json:
        print(json.dumps(r, indent=1))
    else:
        print(f"{sumo_version()}, seed {a.seed}: {r['net']}")
        for k in ("throughput_vph", "tt_mean_s", "tt_main_s", "tt_ramp_s", "trips_main", "trips_ramp",
                  "insert_delay_main_s", "insert_delay_ramp_s", "backlog_end", "loaded", "inserted_total",
                  "running_end", "lane_changes", "collisions", "teleports", "wall_s"):
            print(f"  {k}: {r[k]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
