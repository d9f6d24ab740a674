#!/usr/bin/python3
"""Sparse-control benchmark: automated vehicles (AVs) running wave-damping controllers among human drivers.

For each road (the rings bench/sparse_control/*_ring.yaml and the corridor bottleneck
bench/sparse_control/corridor_bottleneck.yaml) it runs the baseline (no AV) and every controller at every
penetration for several seeds, with `bin/wavefuel run`, and writes into the output directory (default
output/sparse_control/):
  sparse_control.h5   every run's metrics and the seed averages (mean, s.d., change versus baseline)
  results.md          the Markdown tables (fleet, per class, and the field comparison)
  sparse_control.png  fuel change and speed-s.d. change against penetration, per controller and road
Penetrations: rings one vehicle, 2 %, 5 %, 10 % of the fixed fleet (evenly spaced); corridor 2 %, 5 %, 10 % of
the entering vehicles (each vehicle's group drawn at entry by (seed, vehicle)).
Usage:  bench/sparse_control/run.py [--seeds 5] [--jobs N] [--roads sugiyama,long,corridor] [--out DIR] [--reuse]
See bench/sparse_control/README.md for definitions and the measured results.
"""
import argparse
import concurrent.futures as cf
import os
import subprocess
import sys
import time

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))

# kind "ring": a fixed fleet of n vehicles, penetrations are AV counts; kind "corridor": vehicles come from the
# inflow, penetrations are the AV group's fraction of the entering vehicles.
ROADS = {
    "sugiyama": {"kind": "ring", "file": "sugiyama_ring.yaml", "label": "Sugiyama ring (22 veh., 230 m)", "n": 22},
    "long": {"kind": "ring", "file": "long_ring.yaml", "label": "long mixed-fleet ring (3000 veh., 60 km)", "n": 3000},
    # zone_detector_m: the detector inside the work zone; saturated_from_s: from then on the zone's queue exists
    # in every case (checked per run by the detector just upstream of the zone, see read_result).
    "corridor": {"kind": "corridor", "file": "corridor_bottleneck.yaml",
                 "label": "corridor bottleneck (6 km, 6 m/s work zone at 4.0-4.4 km)",
                 "zone_detector_m": 4200.0, "upstream_detector_m": 3900.0, "saturated_from_s": 900.0},
}
# Controller parameters. FollowerStopper's U is not typed in: "baseline" takes the baseline's seed-averaged mean
# speed on the same road (on a ring, the speed the human wave carries), filled in at run time; "speed_limit"
# takes the road's speed limit (corridor only: FollowerStopper as a pure follower that never sets the pace). The
# others run on their defaults; acc_production uses Milanés & Shladover's (2014) production gains, which are
# string unstable. "roads": the road kinds a controller runs on.
CONTROLLERS = {
    "follower_stopper": {"model": "follower_stopper", "params": {}, "U_from": "baseline"},
    "follower_stopper_free": {"model": "follower_stopper", "params": {}, "U_from": "speed_limit",
                              "roads": ("corridor",)},
    "pi_saturation": {"model": "pi_saturation", "params": {}},
    "acc": {"model": "acc", "params": {}},
    "acc_production": {"model": "acc", "params": {"k_gap_per_s2": 0.23, "k_dv_per_s": 0.07}},
    # PI with saturation under the Gipps safety filter on its defaults (docs/controllers.md#safety-filters).
    "pi_saturation_gipps": {"model": "pi_saturation", "params": {}, "safety": {"kind": "gipps"},
                            "roads": ("corridor",)},
}
RING_PENETRATIONS = [("one AV", None), ("2 %", 0.02), ("5 %", 0.05), ("10 %", 0.10)]
CORRIDOR_SHARES = [0.02, 0.05, 0.10]
METRICS = [  # (key in /summary, unit, description)
    ("l_per_100km", "L/100km", "fleet fuel consumption"),
    ("sd_speed_time_avg", "m/s", "time-averaged spatial speed standard deviation"),
    ("hard_brakes_per_vkm", "1/km", "braking events (a < -1 m/s^2) per vehicle-km"),
    ("stops_per_vkm", "1/km", "stops per vehicle-km"),
    ("throughput", "1/h", "ring: passages of x = 0 per hour; corridor: exits at x = L per hour (outflow)"),
    ("infeasible_share", "1", "share of vehicle-steps with an infeasible acceleration request"),
    ("mean_speed", "m/s", "fleet mean speed"),
    ("overlaps", "1", "overlap repairs (collisions)"),
    ("safety_interventions", "1", "steps whose acceleration the AVs' safety filter changed (0 without a filter)"),
]
# Written only for runs with a safety filter: 0 for the others.
OPTIONAL_METRICS = {"safety_interventions"}
# Corridor only (NaN for rings): the entrance and the trips, which a controller that slows the road moves
# vehicles into (vehicles waiting at the entrance burn no fuel in the model and are not in the road's metrics).
CORRIDOR_METRICS = [
    ("inflow", "1/h", "entries at x = 0 per hour in the window"),
    ("mean_travel_time", "s", "mean travel time over the 6 km of the completed trips"),
    ("mean_queue_delay", "s", "mean wait at the entrance of the entered vehicles"),
    ("queued", "1", "vehicles waiting at the entrance at the end of the run"),
    ("zone_flow", "1/h", "flow through the work zone (detector at 4200 m) from t = 900 s, when the queue "
                         "upstream of the zone exists in every case: the bottleneck's discharge rate"),
]
ALL_METRICS = METRICS + CORRIDOR_METRICS
# Stern et al. 2018 (Transp. Res. C 89, 205), Table 3, as transcribed in the literature: one AV on a
# 22-vehicle ring; relative changes versus the human-driven phase.
FIELD = {
    "follower_stopper": {"label": "FollowerStopper, U = 7.5 m/s", "sd": -80.8, "fuel": -42.5,
                         "brakes": (8.58, 0.12), "throughput": +14.1},
    "pi_saturation": {"label": "PI with saturation", "sd": -54.7, "fuel": -28.1, "brakes_change": -74.4,
                      "throughput": -2.5},
}


def av_count(n, share):
    """AVs for a penetration: one vehicle, or round(share * n) but at least one."""
    return 1 if share is None else max(1, int(round(share * n)))


def av_share(road, level):
    """Nominal AV share of a case: a ring's AV count over its fleet, a corridor's group fraction."""
    return level / ROADS[road]["n"] if ROADS[road]["kind"] == "ring" else level


def controllers_for(road, only=None):
    """The controllers that run on a road (only: a subset of them by name, or None for all)."""
    return [c for c, spec in CONTROLLERS.items() if ROADS[road]["kind"] in spec.get("roads", ("ring", "corridor"))
            and (only is None or c in only)]


def read_result(path, road):
    """The metrics of one run file (the corridor's throughput is its outflow)."""
    kind = ROADS[road]["kind"]
    with h5py.File(path, "r") as f:
        s = f["summary"]
        res = {}
        for k, _, _ in METRICS:
            key = "outflow" if (kind == "corridor" and k == "throughput") else k
            res[k] = float(s[key][()]) if key in s or k not in OPTIONAL_METRICS else 0.0
        for k, _, _ in CORRIDOR_METRICS:
            res[k] = float("nan")
        res["zone_saturated"] = float("nan")
        if kind == "corridor":
            for k, _, _ in CORRIDOR_METRICS:
                if k != "zone_flow":  # from the detectors, below
                    res[k] = float(s[k][()])
            res["zone_flow"], res["zone_saturated"] = zone_discharge(f, ROADS[road], path)
        res["class_l_per_100km"] = s["class_l_per_100km"][:].astype(float)
        res["class_names"] = [c.decode() for c in f["classes/name"][:]]
        # Corridor: AVs are the vehicles of driver group 1 that entered (the group is drawn per vehicle).
        res["n_av_run"] = int(np.sum(f["trips/group_id"][:] == 1)) if kind == "corridor" else None
        res["speed_limit_mps"] = float(f["road/speed_limit"][()]) if kind == "corridor" else float("nan")
    return res


def zone_discharge(f, road, path):
    """The corridor's bottleneck discharge: the mean detector flow inside the work zone over the intervals that
    start at or after saturated_from_s, and the share of those intervals in which the detector just upstream of
    the zone saw queue speeds (harmonic mean below 1.5 times the zone's limit, or no passage at all). A share
    below 1 means the zone was starved part of the time and its flow is not its capacity: reported, not hidden."""
    d = f["detectors"]
    x = list(d["x"][:])
    for key in ("zone_detector_m", "upstream_detector_m"):
        if road[key] not in x:
            raise RuntimeError(f"{path}: no detector at x = {road[key]} m (corridor.detectors.x_m)")
    iz, iu = x.index(road["zone_detector_m"]), x.index(road["upstream_detector_m"])
    t0 = d["t_start"][:]
    w = (t0 >= road["saturated_from_s"]) & (d["t_end"][:] - t0 > 0)
    v_zone = float(np.min(f["road/zone_speed_limit"][:]))
    v_up = d["speed_harmonic_mean"][:][w, iu]
    queued = np.where(np.isnan(v_up), True, v_up < 1.5 * v_zone)
    # Intervals may differ in length (the last may be shorter): weight by length.
    dur = (d["t_end"][:] - t0)[w]
    return float(np.sum(d["flow"][:][w, iz] * dur) / np.sum(dur)), float(np.mean(queued))


def cached(job):
    """True if OUT/runs holds a completed run of exactly this job: same scenario text and the same --set list
    (both recorded in /meta). It assumes the binary has not changed the physics since."""
    try:
        with h5py.File(job["out"], "r") as f:
            m = f["meta"]
            with open(job["scenario"]) as sf:
                text = sf.read()
            return (int(m["completed"][()]) == 1 and m["scenario_text"][()].decode() == text
                    and m["overrides"][()].decode() == "".join(s + "\n" for s in job["sets"]))
    except (OSError, KeyError):
        return False


def run_one(job):
    """One `wavefuel run` (or its cached file with --reuse); returns the job with its metrics."""
    scen, out, sets = job["scenario"], job["out"], job["sets"]
    if job["reuse"] and cached(job):
        return dict(job, result=read_result(out, job["road"]), reused=True)
    cmd = [os.path.join(ROOT, "bin", "wavefuel"), "run", scen, "-q", "--force", "-o", out]
    for s in sets:
        cmd += ["--set", s]
    env = dict(os.environ, OMP_NUM_THREADS="1")
    p = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({p.returncode}): {p.stderr.strip()}")
    return dict(job, result=read_result(out, job["road"]), reused=False)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=5, help="seeds 1..N per case (default 5)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="runs at once (default: cores)")
    ap.add_argument("--roads", "--rings", dest="roads", default="sugiyama,long,corridor",
                    help="comma-separated: " + ",".join(ROADS))
    ap.add_argument("--controllers", default=None,
                    help="comma-separated subset of: " + ",".join(CONTROLLERS) + " (default: all)")
    ap.add_argument("--out", default=os.path.join(ROOT, "output", "sparse_control"))
    ap.add_argument("--reuse", action="store_true",
                    help="read runs already in OUT/runs whose scenario text and --set list match instead of "
                         "running them again")
    args = ap.parse_args()
    roads = [r for r in args.roads.split(",") if r]
    for r in roads:
        if r not in ROADS:
            sys.exit(f"unknown road '{r}' (known: {', '.join(ROADS)})")
    only = args.controllers.split(",") if args.controllers else None
    for c in only or []:
        if c not in CONTROLLERS:
            sys.exit(f"unknown controller '{c}' (known: {', '.join(CONTROLLERS)})")
    os.makedirs(os.path.join(args.out, "runs"), exist_ok=True)
    seeds = list(range(1, args.seeds + 1))
    t0 = time.time()
    pool = cf.ThreadPoolExecutor(max_workers=args.jobs)

    def job(road, ctrl, level, seed, sets):
        # Ring files keep their historical names (AV count); corridor files name the share in percent.
        tag = level if ROADS[road]["kind"] == "ring" else f"{round(100 * level):d}pct"
        name = f"{road}_{ctrl}_{tag}_{seed}"
        return {"road": road, "controller": ctrl, "level": level, "seed": seed, "name": name,
                "scenario": os.path.join(HERE, ROADS[road]["file"]), "reuse": args.reuse,
                "out": os.path.join(args.out, "runs", name + ".h5"), "sets": sets}

    runs = []
    # Baselines first: FollowerStopper's U comes from them. A corridor baseline is the AV group at fraction 0.
    base_jobs = [job(r, "baseline", 0, s, [f"seed={s}"]) for r in roads for s in seeds]
    runs += list(pool.map(run_one, base_jobs))
    base_speed = {r: float(np.mean([x["result"]["mean_speed"] for x in runs if x["road"] == r])) for r in roads}
    jobs, U = [], {}
    for r in roads:
        road = ROADS[r]
        if road["kind"] == "ring":
            n = road["n"]
            levels = sorted({av_count(n, share) for _, share in RING_PENETRATIONS})
        else:
            levels = CORRIDOR_SHARES
        for c in controllers_for(r, only):
            spec = CONTROLLERS[c]
            params = dict(spec["params"])
            if spec.get("U_from") == "baseline":
                params["U_mps"] = round(base_speed[r], 3)
            elif spec.get("U_from") == "speed_limit":
                params["U_mps"] = next(x["result"]["speed_limit_mps"] for x in runs if x["road"] == r)
            if "U_mps" in params:
                U[(r, c)] = params["U_mps"]
            for level in levels:
                for s in seeds:
                    if road["kind"] == "ring":
                        sets = [f"seed={s}", f"fleet.drivers[0].count={road['n'] - level}",
                                f"fleet.drivers[1].count={level}"]
                    else:
                        # Fractions must sum to 1; %.10g prints 1 - 0.02 as 0.98.
                        sets = [f"seed={s}", f"fleet.drivers[0].fraction={1.0 - level:.10g}",
                                f"fleet.drivers[1].fraction={level:.10g}"]
                    sets += [f"fleet.drivers[1].model={spec['model']}"]
                    sets += [f"fleet.drivers[1].params.{k}={v}" for k, v in params.items()]
                    sets += [f"fleet.drivers[1].safety.{k}={v}" for k, v in spec.get("safety", {}).items()]
                    jobs.append(job(r, c, level, s, sets))
    done = 0
    for res in pool.map(run_one, jobs):
        runs.append(res)
        done += 1
        if done % 20 == 0:
            print(f"  {done}/{len(jobs)} controller runs ({time.time() - t0:.0f} s)", flush=True)
    pool.shutdown()
    wall = time.time() - t0
    n_reused = sum(1 for x in runs if x["reused"])
    agg = aggregate(runs)
    write_h5(os.path.join(args.out, "sparse_control.h5"), runs, agg, roads, seeds, U, wall, n_reused)
    md = markdown(agg, roads, seeds, U, wall, len(runs) - n_reused, n_reused)
    with open(os.path.join(args.out, "results.md"), "w") as f:
        f.write(md)
    plot(os.path.join(args.out, "sparse_control.png"), agg, roads)
    print(md)
    print(f"wrote {args.out}/sparse_control.h5, results.md, sparse_control.png "
          f"({len(runs)} runs, {n_reused} reused, {wall:.0f} s)")


def aggregate(runs):
    """Per (road, controller, level): mean and s.d. over seeds of each metric, and of its relative change versus
    the baseline run with the same seed (paired, so the common noise cancels)."""
    base = {(x["road"], x["seed"]): x["result"] for x in runs if x["controller"] == "baseline"}
    cases = {}
    for x in runs:
        cases.setdefault((x["road"], x["controller"], x["level"]), []).append(x)
    agg = {}
    for key, xs in sorted(cases.items(), key=lambda kv: (kv[0][0], kv[0][1] != "baseline", kv[0][1], kv[0][2])):
        xs.sort(key=lambda x: x["seed"])
        a = {"n_seeds": len(xs)}
        for m, _, _ in ALL_METRICS + [("class_l_per_100km", "", "")]:
            vals = np.array([x["result"][m] for x in xs])
            b = np.array([base[(x["road"], x["seed"])][m] for x in xs])
            # Relative change; undefined (NaN) where the baseline is 0 (overlaps, infeasible share) or NaN
            # (the corridor metrics on rings).
            with np.errstate(divide="ignore", invalid="ignore"):
                rel = np.where(b != 0, 100.0 * (vals / np.where(b != 0, b, 1.0) - 1.0), np.nan)
            a[m] = (vals.mean(axis=0), vals.std(axis=0, ddof=1) if len(xs) > 1 else 0 * vals[0])
            a[m + "_change"] = (rel.mean(axis=0), rel.std(axis=0, ddof=1) if len(xs) > 1 else 0 * rel[0])
        a["class_names"] = xs[0]["result"]["class_names"]
        # AVs per run: a ring's count, or the AVs that entered the corridor (mean over seeds).
        a["n_av"] = (float(np.mean([x["result"]["n_av_run"] for x in xs]))
                     if ROADS[key[0]]["kind"] == "corridor" else float(key[2]))
        a["av_share"] = av_share(key[0], key[2])
        a["zone_saturated_min"] = float(np.min([x["result"]["zone_saturated"] for x in xs]))
        agg[key] = a
    return agg


def write_h5(path, runs, agg, roads, seeds, U, wall, n_reused):
    tmp = path + ".partial"
    with h5py.File(tmp, "w") as f:
        f.attrs["description"] = "wavefuel sparse-control benchmark (bench/sparse_control/README.md)"
        f.attrs["seeds"] = np.array(seeds)
        f.attrs["wall_time_s"] = wall
        f.attrs["runs_reused"] = n_reused
        for (r, c), u in U.items():
            # Historical name for the rings' FollowerStopper; the corridor's two variants by controller name.
            f.attrs[f"follower_stopper_U_mps_{r}" if c == "follower_stopper" else f"{c}_U_mps_{r}"] = u
        g = f.create_group("runs")
        str_cols = {"road": [x["road"] for x in runs], "controller": [x["controller"] for x in runs]}
        for k, v in str_cols.items():
            g.create_dataset(k, data=np.array(v, dtype=h5py.string_dtype())).attrs["units"] = "1"
        n_av = [x["level"] if ROADS[x["road"]]["kind"] == "ring" else x["result"]["n_av_run"] for x in runs]
        d = g.create_dataset("n_av", data=np.array(n_av, dtype=np.int64))
        d.attrs["units"], d.attrs["description"] = "1", "AVs in the run (corridor: AVs that entered)"
        d = g.create_dataset("av_share", data=np.array([av_share(x["road"], x["level"]) for x in runs]))
        d.attrs["units"], d.attrs["description"] = "1", "nominal AV share (ring: count / fleet; corridor: fraction)"
        g.create_dataset("seed", data=np.array([x["seed"] for x in runs], dtype=np.int64)).attrs["units"] = "1"
        for m, unit, desc in ALL_METRICS:
            d = g.create_dataset(m, data=np.array([x["result"][m] for x in runs]))
            d.attrs["units"], d.attrs["description"] = unit, desc
        d = g.create_dataset("zone_saturated", data=np.array([x["result"]["zone_saturated"] for x in runs]))
        d.attrs["units"] = "1"
        d.attrs["description"] = ("corridor: share of the detector intervals behind zone_flow with queue speeds just "
                                  "upstream of the zone (1: the zone was saturated throughout); NaN for rings")
        ga = f.create_group("aggregate")
        keys = list(agg)
        for k, v in (("road", [k[0] for k in keys]), ("controller", [k[1] for k in keys])):
            ga.create_dataset(k, data=np.array(v, dtype=h5py.string_dtype())).attrs["units"] = "1"
        d = ga.create_dataset("n_av", data=np.array([agg[k]["n_av"] for k in keys]))
        d.attrs["units"], d.attrs["description"] = "1", "AVs per run, mean over seeds (corridor: AVs that entered)"
        d = ga.create_dataset("av_share", data=np.array([agg[k]["av_share"] for k in keys]))
        d.attrs["units"], d.attrs["description"] = "1", "nominal AV share (ring: count / fleet; corridor: fraction)"
        for m, unit, desc in ALL_METRICS:
            for suffix, u2, what in (("", unit, desc), ("_change", "%", "relative change versus baseline, %")):
                for i, stat in enumerate(("mean", "sd")):
                    d = ga.create_dataset(f"{m}{suffix}_{stat}", data=np.array([agg[k][m + suffix][i] for k in keys]))
                    d.attrs["units"] = u2
                    d.attrs["description"] = f"{desc}{'' if not suffix else ': ' + what}, {stat} over seeds"
        for r in roads:
            gc = ga.create_group(f"class_{r}")
            rk = [k for k in keys if k[0] == r]
            for name, data in (("class", np.array(agg[rk[0]]["class_names"], dtype=h5py.string_dtype())),
                               ("controller", np.array([k[1] for k in rk], dtype=h5py.string_dtype())),
                               ("n_av", np.array([agg[k]["n_av"] for k in rk])),
                               ("av_share", np.array([agg[k]["av_share"] for k in rk]))):
                gc.create_dataset(name, data=data).attrs["units"] = "1"
            for suffix, unit in (("", "L/100km"), ("_change", "%")):
                d = gc.create_dataset("l_per_100km" + suffix + "_mean",
                                      data=np.array([agg[k]["class_l_per_100km" + suffix][0] for k in rk]))
                d.attrs["units"] = unit
        gf = f.create_group("field_stern2018")
        gf.attrs["source"] = "Stern et al. 2018, Transp. Res. C 89, 205, Table 3 (as transcribed)"
        for c, v in FIELD.items():
            gg = gf.create_group(c)
            for k, val in v.items():
                gg.attrs[k] = val
    os.replace(tmp, path)


def fmt(mean, sd, digits=2):
    return f"{mean:.{digits}f} ± {sd:.{digits}f}"


def ring_tables(agg, r, U):
    out = []
    n = ROADS[r]["n"]
    out.append(f"\n### {ROADS[r]['label']}: fleet\n")
    out.append(f"FollowerStopper U = {U[(r, 'follower_stopper')]:.3f} m/s (the baseline's mean speed).\n")
    out.append("| controller | AVs | fuel L/100km | Δ fuel % | speed s.d. m/s | Δ s.d. % | braking /vkm "
               "| stops /vkm | throughput veh/h | Δ thr. % | infeasible % | overlaps |")
    out.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for (road, c, n_av), a in agg.items():
        if road != r:
            continue
        pen = f"{n_av} ({100.0 * n_av / n:.1f} %)"
        out.append(
            f"| {c} | {pen} | {fmt(*a['l_per_100km'])} | {fmt(*a['l_per_100km_change'], 1)} "
            f"| {fmt(*a['sd_speed_time_avg'])} | {fmt(*a['sd_speed_time_avg_change'], 1)} "
            f"| {fmt(*a['hard_brakes_per_vkm'])} | {fmt(*a['stops_per_vkm'])} | {a['throughput'][0]:.0f} "
            f"| {fmt(*a['throughput_change'], 1)} | {100 * a['infeasible_share'][0]:.3f} "
            f"| {a['overlaps'][0]:.1f} |")
    return out


def corridor_tables(agg, r, U):
    out = [f"\n### {ROADS[r]['label']}: fleet\n"]
    if (r, "follower_stopper") in U and (r, "follower_stopper_free") in U:
        out.append(f"FollowerStopper U = {U[(r, 'follower_stopper')]:.3f} m/s (the baseline's mean speed); "
                   f"follower_stopper_free U = {U[(r, 'follower_stopper_free')]:.1f} m/s (the road's speed limit). ")
    out.append("AVs: the nominal share of the entering vehicles (the AVs that entered, mean over seeds). "
               "Throughput: exits per hour (outflow); travel time over the 6 km (completed trips); entry wait: "
               "mean wait at the entrance.\n")
    out.append("| controller | AVs | fuel L/100km | Δ fuel % | speed s.d. m/s | Δ s.d. % | braking /vkm "
               "| stops /vkm | outflow veh/h | Δ outflow % | zone flow veh/h | Δ zone % | infeasible % | overlaps "
               "| travel time s | entry wait s |")
    out.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for (road, c, share), a in agg.items():
        if road != r:
            continue
        pen = f"{100 * share:.0f} % ({a['n_av']:.1f})"
        out.append(
            f"| {c} | {pen} | {fmt(*a['l_per_100km'])} | {fmt(*a['l_per_100km_change'], 1)} "
            f"| {fmt(*a['sd_speed_time_avg'])} | {fmt(*a['sd_speed_time_avg_change'], 1)} "
            f"| {fmt(*a['hard_brakes_per_vkm'])} | {fmt(*a['stops_per_vkm'], 3)} | {fmt(*a['throughput'], 0)} "
            f"| {fmt(*a['throughput_change'], 1)} | {fmt(*a['zone_flow'], 0)} | {fmt(*a['zone_flow_change'], 1)} "
            f"| {100 * a['infeasible_share'][0]:.3f} | {a['overlaps'][0]:.1f} | {fmt(*a['mean_travel_time'], 0)} "
            f"| {fmt(*a['mean_queue_delay'], 0)} |")
    starved = [f"{c} {100 * share:.0f} % ({a['zone_saturated_min']:.2f})"
               for (road, c, share), a in agg.items() if road == r and a["zone_saturated_min"] < 1.0]
    sat = ROADS[r]["saturated_from_s"]
    out.append(f"\nZone flow: the detector in the work zone from t = {sat:.0f} s. "
               + ("The queue upstream of the zone was present in every interval of every run."
                  if not starved else "Runs whose zone was not saturated in every interval (smallest share of "
                  "queued intervals over seeds): " + ", ".join(starved) + "."))
    if any("safety" in CONTROLLERS.get(c, {}) for (road, c, _) in agg if road == r):
        out.append(f"\n### {ROADS[r]['label']}: safety filter\n")
        out.append("Interventions: the AVs' steps whose acceleration the filter changed, per run (whole run).\n")
        out.append("| controller | AV share | fuel L/100km | Δ fuel % | braking /vkm | stops /vkm | travel time s "
                   "| overlaps | interventions |")
        out.append("|---|---|---|---|---|---|---|---|---|")
        for (road, c, share), a in agg.items():
            if road == r and c != "baseline":
                out.append(f"| {c} | {100 * share:.0f} % | {fmt(*a['l_per_100km'])} | {fmt(*a['l_per_100km_change'], 1)} "
                           f"| {fmt(*a['hard_brakes_per_vkm'])} | {fmt(*a['stops_per_vkm'], 3)} "
                           f"| {fmt(*a['mean_travel_time'], 0)} | {fmt(*a['overlaps'], 1)} "
                           f"| {fmt(*a['safety_interventions'], 0)} |")
    return out


def markdown(agg, roads, seeds, U, wall, n_run, n_reused):
    reused = f" ({n_run} runs executed, {n_reused} read from earlier runs with --reuse)" if n_reused else ""
    out = [f"Seeds {seeds[0]}..{seeds[-1]} per case; mean ± s.d. over seeds; changes are paired with the "
           f"baseline run of the same seed. Wall time {wall:.0f} s{reused}.\n"]
    for r in roads:
        out += ring_tables(agg, r, U) if ROADS[r]["kind"] == "ring" else corridor_tables(agg, r, U)
        names = next(a["class_names"] for k, a in agg.items() if k[0] == r)
        if len(names) > 1:
            ring = ROADS[r]["kind"] == "ring"
            out.append(f"\n### {ROADS[r]['label']}: fuel per class, L/100km (Δ % versus baseline)\n")
            out.append(f"| controller | {'AVs' if ring else 'AV share'} | " + " | ".join(names) + " |")
            out.append("|---|---|" + "---|" * len(names))
            for (road, c, level), a in agg.items():
                if road != r:
                    continue
                cells = [f"{a['class_l_per_100km'][0][i]:.2f} ({a['class_l_per_100km_change'][0][i]:+.1f})"
                         for i in range(len(names))]
                lv = f"{level}" if ring else f"{100 * level:.0f} %"
                out.append(f"| {c} | {lv} | " + " | ".join(cells) + " |")
    if "sugiyama" in roads and all(("sugiyama", c, 1) in agg for c in FIELD):
        out.append("\n### One AV on the Sugiyama ring beside the field experiment (Stern et al. 2018, Table 3)\n")
        out.append("| controller | | speed s.d. Δ % | fuel Δ % | braking events /vkm | throughput Δ % |")
        out.append("|---|---|---|---|---|---|")
        base = agg[("sugiyama", "baseline", 0)]
        for c, fv in FIELD.items():
            a = agg[("sugiyama", c, 1)]
            fb = (f"{fv['brakes'][0]} → {fv['brakes'][1]}" if "brakes" in fv
                  else f"{fv['brakes_change']:+.1f} %")
            out.append(f"| {fv['label']} | field | {fv['sd']:+.1f} | {fv['fuel']:+.1f} | {fb} "
                       f"| {fv['throughput']:+.1f} |")
            brk = 100 * (a["hard_brakes_per_vkm"][0] / base["hard_brakes_per_vkm"][0] - 1)
            out.append(f"| {c} (U = {U[('sugiyama', c)]:.2f} m/s) | wavefuel | " if c == "follower_stopper" else
                       f"| {c} | wavefuel | ")
            out[-1] += (f"{a['sd_speed_time_avg_change'][0]:+.1f} | {a['l_per_100km_change'][0]:+.1f} "
                        f"| {base['hard_brakes_per_vkm'][0]:.2f} → {a['hard_brakes_per_vkm'][0]:.2f} "
                        f"({brk:+.1f} %) | {a['throughput_change'][0]:+.1f} |")
    return "\n".join(out) + "\n"


def plot(path, agg, roads):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    # One colour per controller in every panel (the rings' panels keep their historical colours).
    colour = {"follower_stopper": "C0", "pi_saturation": "C1", "acc": "C2", "acc_production": "C3",
              "follower_stopper_free": "C4", "pi_saturation_gipps": "C5"}
    fig, ax = plt.subplots(2, len(roads), figsize=(5.5 * len(roads), 7.6), squeeze=False)
    for j, r in enumerate(roads):
        for c in controllers_for(r):
            ks = sorted(k for k in agg if k[0] == r and k[1] == c)
            if not ks:  # not run (--controllers)
                continue
            x = [100.0 * av_share(r, k[2]) for k in ks]
            for i, m in enumerate(("l_per_100km_change", "sd_speed_time_avg_change")):
                mean = [agg[k][m][0] for k in ks]
                sd = [agg[k][m][1] for k in ks]
                ax[i][j].errorbar(x, mean, yerr=sd, marker="o", capsize=3, label=c, color=colour.get(c))
        ax[0][j].set_title(ROADS[r]["label"], fontsize=10)
        ax[0][j].set_ylabel("fleet fuel change vs baseline (%)")
        ax[1][j].set_ylabel("speed s.d. change vs baseline (%)")
        ticks = sorted({100.0 * av_share(r, k[2]) for k in agg if k[0] == r and k[2] > 0})
        unit = "of vehicles" if ROADS[r]["kind"] == "ring" else "of entering vehicles"
        for i in range(2):
            ax[i][j].axhline(0.0, color="grey", lw=0.8)
            ax[i][j].set_xscale("log")
            ax[i][j].set_xticks(ticks, [f"{t:.2g}" for t in ticks])
            ax[i][j].minorticks_off()
            ax[i][j].set_xlabel(f"AV penetration (% {unit})")
            ax[i][j].grid(alpha=0.3)
        # Below the panels: inside, the legend hid lines of one panel or another.
        h, lab = ax[0][j].get_legend_handles_labels()
        ax[1][j].legend(h, lab, fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    main()
