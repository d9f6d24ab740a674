#!/usr/bin/python3
"""wavefuel against SUMO on the three-lane corridor with on-ramp and lane drop (issue 18), seeds 1-3, side by side.

SUMO (sumo_corridor.py): IDM + LC2013 defaults, for each departSpeed in --depart-speeds ("last": a vehicle enters at
the speed of the last vehicle on its lane, SUMO's nearest to wavefuel's insertion rule, which inserts at the leader's
speed; "max": the highest speed SUMO deems safe, SUMO's usual choice for saturated entrances). wavefuel:
`bin/wavefuel run bench/lanes_sumo/corridor.yaml --set seed=S --set road.lane_rule=R` for each rule in --rules
(keep_right: MOBIL's European rules, the nearer to LC2013's keepRight; symmetric: MOBIL's default rule), when the
binary exists and accepts the scenario (corridor.on_ramp with start_m/end_m and corridor.lane_drops: main 5d89e00).

Per run: throughput (exits at x = 6000 m per hour over 600-3600 s), mean travel time of the completed trips inserted
after the warm-up (all, main, ramp; from insertion, so the wait at the entrance is not in it: it is reported apart as
the mean insertion delay), the insertion backlog at the end (SUMO: loaded but not inserted; wavefuel:
/summary/queued, main entrance and ramp), vehicles on the road at the end, lane changes, ramp vehicles that merged.
The table gives each configuration's mean over the seeds (min-max in brackets for the two compared figures) and the
ratio to SUMO's "last" configuration against issue 18's bounds (throughput within 15 %, travel time within 20 %).
Writes bench/lanes_sumo/results.json; --table prints the table of an existing results.json again.
Usage: /usr/bin/python3 bench/lanes_sumo/run.py [--seeds 1,2,3] [--jobs 2] [--depart-speeds last,max]
                                                [--rules keep_right,symmetric] [--bin bin/wavefuel]
                                                [--main-vph 4200] [--ramp-vph 700] [--lc-params ATTRS]
                                                [--wf-set KEY=VALUE]... [--reuse-sumo] [--out FILE] [--table]
(--depart-speeds '' or --rules '' leave a side out; README.md lists the commands of every results file.)"""
import argparse
import concurrent.futures as cf
import datetime
import json
import os
import subprocess
import sys
import tempfile
import time

import sumo_corridor as sc

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SCENARIO = os.path.join(HERE, "corridor.yaml")
RESULTS = os.path.join(HERE, "results.json")
RAMP_KEY = 2 ** 40  # a corridor vehicle's /trips/serial is lane * 2^40 + its count in the lane (docs/lanes.md)


def sumo_one(args):
    seed, depart_speed, demand, lc_params = args
    r = sc.run(seed, None, dict(sc.SCEN, depart_speed=depart_speed, lc_params=lc_params, **demand))
    r.pop("netconvert_messages", None)
    return r


def wavefuel_available(binary):
    if not os.path.exists(binary):
        return f"{binary} not built (make)"
    with tempfile.TemporaryDirectory() as d:
        r = subprocess.run([binary, "run", SCENARIO, "-q", "-o", os.path.join(d, "x.h5"), "--set",
                            "time.duration_s=1", "--set", "time.warmup_s=0"], capture_output=True, text=True)
    if r.returncode != 0:
        return f"{binary} refuses {os.path.relpath(SCENARIO, ROOT)}: {(r.stderr or r.stdout).strip()[:300]}"
    return None


def wavefuel_one(binary, seed, rule, extra=()):
    import h5py
    import numpy as np
    w0 = sc.SCEN["warmup_s"]
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "run.h5")
        cmd = [binary, "run", SCENARIO, "-q", "-o", out, "--set", f"seed={seed}", "--set", f"road.lane_rule={rule}",
               "--threads", "1"] + [x for kv in extra for x in ("--set", kv)]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True, text=True, cwd=ROOT)
        wall = time.perf_counter() - t0
        with h5py.File(out) as f:
            t = {k: f["trips"][k][:] for k in ("serial", "completed", "entry_time", "travel_time", "queue_delay")}
            s = {k: f["summary"][k][()] for k in ("outflow", "inflow", "queued", "on_road", "lane_changes",
                                                   "overlaps")}
            pair = f["lanes/pair_changes"][:]
    ramp = (t["serial"] // RAMP_KEY) == 0
    after = t["entry_time"] >= w0
    done = (t["completed"] == 1) & after
    mean = lambda m, x: float(np.mean(x[m])) if m.any() else float("nan")
    return dict(seed=seed, rule=rule, wall_s=wall,
                throughput_vph=float(s["outflow"]), inflow_vph=float(s["inflow"]),
                tt_mean_s=mean(done, t["travel_time"]), tt_main_s=mean(done & ~ramp, t["travel_time"]),
                tt_ramp_s=mean(done & ramp, t["travel_time"]),
                trips_main=int((done & ~ramp).sum()), trips_ramp=int((done & ramp).sum()),
                insert_delay_main_s=mean(after & ~ramp, t["queue_delay"]),
                insert_delay_ramp_s=mean(after & ramp, t["queue_delay"]),
                ramp_entered=int(ramp.sum()), ramp_merged=int(pair[0, 1]), drop_merged=int(pair[3, 2]),
                backlog_end=int(s["queued"]), running_end=int(s["on_road"]),
                lane_changes=int(s["lane_changes"]), overlaps=int(s["overlaps"]))


def summarise(runs, key):
    vals = [r[key] for r in runs]
    return sum(vals) / len(vals), min(vals), max(vals)


def table(res):
    if not res["sumo"]:
        return "(no SUMO runs)"
    ref = res["sumo"].get("last") or next(iter(res["sumo"].values()))  # else the first configuration
    ref_q, ref_t = summarise(ref, "throughput_vph")[0], summarise(ref, "tt_mean_s")[0]
    rows = [(f"SUMO IDM + LC2013, departSpeed {k}", v) for k, v in res["sumo"].items()]
    rows += [(f"wavefuel IDM + MOBIL, {k}", v) for k, v in res.get("wavefuel", {}).items()]
    lines = ["| configuration (mean of seeds " + ",".join(str(s) for s in res["seeds"]) + ") | throughput veh/h "
             "[min-max] | vs SUMO last | mean travel time s [min-max] | vs SUMO last | main / ramp travel time s | "
             "mean insertion delay main / ramp s | backlog at end | on road at end | lane changes |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name, runs in rows:
        q, qlo, qhi = summarise(runs, "throughput_vph")
        tt, tlo, thi = summarise(runs, "tt_mean_s")
        lc = summarise(runs, "lane_changes")[0] if not isinstance(runs[0]["lane_changes"], dict) else \
            sum(r["lane_changes"]["total"] for r in runs) / len(runs)
        dq, dt = q / ref_q - 1, tt / ref_t - 1
        lines.append(
            f"| {name} | {q:.0f} [{qlo:.0f}-{qhi:.0f}] | {100 * dq:+.1f} % {'ok' if abs(dq) <= 0.15 else 'OUT'} | "
            f"{tt:.0f} [{tlo:.0f}-{thi:.0f}] | {100 * dt:+.1f} % {'ok' if abs(dt) <= 0.20 else 'OUT'} | "
            f"{summarise(runs, 'tt_main_s')[0]:.0f} / {summarise(runs, 'tt_ramp_s')[0]:.0f} | "
            f"{summarise(runs, 'insert_delay_main_s')[0]:.1f} / {summarise(runs, 'insert_delay_ramp_s')[0]:.1f} | "
            f"{summarise(runs, 'backlog_end')[0]:.0f} | {summarise(runs, 'running_end')[0]:.0f} | {lc:.0f} |")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--jobs", type=int, default=2, help="SUMO runs at once")
    ap.add_argument("--depart-speeds", default="last,max")
    ap.add_argument("--rules", default="keep_right,symmetric")
    ap.add_argument("--bin", default=os.path.join(ROOT, "bin", "wavefuel"))
    ap.add_argument("--main-vph", type=float, default=sc.SCEN["main_vph"], help="main demand, both sides")
    ap.add_argument("--ramp-vph", type=float, default=sc.SCEN["ramp_vph"], help="ramp demand, both sides")
    ap.add_argument("--lc-params", default="",
                    help='extra SUMO vType attributes, e.g. \'lcCooperative="0"\' (diagnostics)')
    ap.add_argument("--wf-set", action="append", default=[],
                    help="extra --set KEY=VALUE for wavefuel (diagnostics), repeatable")
    ap.add_argument("--out", default=RESULTS, help="results file (default bench/lanes_sumo/results.json)")
    ap.add_argument("--reuse-sumo", action="store_true",
                    help="keep the SUMO runs already in the results file (same demand), rerun only wavefuel")
    ap.add_argument("--table", action="store_true", help="print the table of the results file again")
    a = ap.parse_args()
    if a.table:
        with open(a.out) as f:
            print(table(json.load(f)))
        return 0
    seeds = [int(s) for s in a.seeds.split(",")]
    demand = dict(main_vph=a.main_vph, ramp_vph=a.ramp_vph)
    res = dict(seeds=seeds, date=datetime.datetime.utcnow().strftime("%Y-%m-%d %H:%M UTC"),
               load_before=os.getloadavg()[0], scenario=dict(sc.SCEN, **demand), sumo={}, wavefuel={})
    wf_demand = [f"corridor.inflow.flow_vph={a.main_vph:g}", f"corridor.on_ramp.flow_vph={a.ramp_vph:g}"]
    why = sc.available() if a.depart_speeds else "not asked for (--depart-speeds '')"
    if a.reuse_sumo:
        with open(a.out) as f:
            old = json.load(f)
        if (old["scenario"]["main_vph"], old["scenario"]["ramp_vph"]) != (a.main_vph, a.ramp_vph):
            raise SystemExit(f"{a.out}: another demand than --main-vph/--ramp-vph")
        for k in ("sumo", "sumo_version"):
            if k in old:
                res[k] = old[k]
        res["sumo_date"] = old.get("sumo_date", old["date"])
        why = f"reused from {a.out} ({res['sumo_date']})"
    if why:
        print(f"SUMO: not run: {why}")
    else:
        res["sumo_version"] = sc.sumo_version()
        jobs = [(s, ds, demand, a.lc_params) for ds in a.depart_speeds.split(",") for s in seeds]
        with cf.ProcessPoolExecutor(a.jobs) as ex:
            for (s, ds, _, _), r in zip(jobs, ex.map(sumo_one, jobs)):
                res["sumo"].setdefault(ds + (f", {a.lc_params}" if a.lc_params else ""), []).append(r)
                print(f"SUMO departSpeed {ds} seed {s}: {r['throughput_vph']:.0f} veh/h, {r['tt_mean_s']:.1f} s, "
                      f"backlog {r['backlog_end']}, wall {r['wall_s']:.0f} s", flush=True)
    why = wavefuel_available(a.bin) if a.rules else "not asked for (--rules '')"
    if why:
        print(f"wavefuel: not run: {why}")
        res["wavefuel_not_run"] = why
    else:
        res["wavefuel_commit"] = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"],
                                                capture_output=True, text=True).stdout.strip()
        for rule in a.rules.split(","):
            for s in seeds:
                r = wavefuel_one(a.bin, s, rule, wf_demand + a.wf_set)
                res["wavefuel"].setdefault(rule + "".join(f", {x}" for x in a.wf_set), []).append(r)
                print(f"wavefuel {rule} seed {s}: {r['throughput_vph']:.0f} veh/h, {r['tt_mean_s']:.1f} s, "
                      f"ramp entered {r['ramp_entered']}, backlog {r['backlog_end']}", flush=True)
    res["load_after"] = os.getloadavg()[0]
    with open(a.out, "w") as f:
        json.dump(res, f, indent=1)
    if res["sumo"]:
        print(table(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
