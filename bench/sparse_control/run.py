#!/usr/bin/python3
"""Sparse-control benchmark: automated vehicles (AVs) running wave-damping controllers among human drivers.

For each ring (bench/sparse_control/*_ring.yaml) it runs the baseline (no AV) and every controller at every
penetration (one vehicle, 2 %, 5 %, 10 %; AVs evenly spaced) for several seeds, with `bin/wavefuel run`, and
writes into the output directory (default output/sparse_control/):
  sparse_control.h5   every run's metrics and the seed averages (mean, s.d., change versus baseline)
  results.md          the Markdown tables (fleet, per class, and the field comparison)
  sparse_control.png  fuel change and speed-s.d. change against penetration, per controller and ring
Usage:  bench/sparse_control/run.py [--seeds 5] [--jobs N] [--rings sugiyama,long] [--out DIR]
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

RINGS = {
    "sugiyama": {"file": "sugiyama_ring.yaml", "label": "Sugiyama ring (22 veh., 230 m)", "n": 22},
    "long": {"file": "long_ring.yaml", "label": "long mixed-fleet ring (3000 veh., 60 km)", "n": 3000},
}
# Controller parameters. FollowerStopper's U is not typed in: it is the baseline's seed-averaged mean speed on
# the same ring (the speed the human wave carries), filled in at run time. The others run on their defaults;
# acc_production uses Milanés & Shladover's (2014) production gains, which are string unstable.
CONTROLLERS = {
    "follower_stopper": {"model": "follower_stopper", "params": {}, "U_from_baseline": True},
    "pi_saturation": {"model": "pi_saturation", "params": {}},
    "acc": {"model": "acc", "params": {}},
    "acc_production": {"model": "acc", "params": {"k_gap_per_s2": 0.23, "k_dv_per_s": 0.07}},
}
PENETRATIONS = [("one AV", None), ("2 %", 0.02), ("5 %", 0.05), ("10 %", 0.10)]
METRICS = [  # (key in /summary, unit, description)
    ("l_per_100km", "L/100km", "fleet fuel consumption"),
    ("sd_speed_time_avg", "m/s", "time-averaged spatial speed standard deviation"),
    ("hard_brakes_per_vkm", "1/km", "braking events (a < -1 m/s^2) per vehicle-km"),
    ("stops_per_vkm", "1/km", "stops per vehicle-km"),
    ("throughput", "1/h", "passages of x = 0 per hour"),
    ("infeasible_share", "1", "share of vehicle-steps with an infeasible acceleration request"),
    ("mean_speed", "m/s", "fleet mean speed"),
    ("overlaps", "1", "overlap repairs (collisions)"),
]
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


def run_one(job):
    """One `wavefuel run`; returns the job with its summary metrics and per-class fuel."""
    scen, out, sets = job["scenario"], job["out"], job["sets"]
    cmd = [os.path.join(ROOT, "bin", "wavefuel"), "run", scen, "-q", "--force", "-o", out]
    for s in sets:
        cmd += ["--set", s]
    env = dict(os.environ, OMP_NUM_THREADS="1")
    p = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({p.returncode}): {p.stderr.strip()}")
    with h5py.File(out, "r") as f:
        s = f["summary"]
        res = {k: float(s[k][()]) for k, _, _ in METRICS}
        res["class_l_per_100km"] = s["class_l_per_100km"][:].astype(float)
        res["class_names"] = [c.decode() for c in f["classes/name"][:]]
    return dict(job, result=res)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=5, help="seeds 1..N per case (default 5)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="runs at once (default: cores)")
    ap.add_argument("--rings", default="sugiyama,long", help="comma-separated: " + ",".join(RINGS))
    ap.add_argument("--out", default=os.path.join(ROOT, "output", "sparse_control"))
    args = ap.parse_args()
    rings = [r for r in args.rings.split(",") if r]
    for r in rings:
        if r not in RINGS:
            sys.exit(f"unknown ring '{r}' (known: {', '.join(RINGS)})")
    os.makedirs(os.path.join(args.out, "runs"), exist_ok=True)
    seeds = list(range(1, args.seeds + 1))
    t0 = time.time()
    pool = cf.ThreadPoolExecutor(max_workers=args.jobs)

    def job(ring, ctrl, n_av, seed, sets):
        name = f"{ring}_{ctrl}_{n_av}_{seed}"
        return {"ring": ring, "controller": ctrl, "n_av": n_av, "seed": seed, "name": name,
                "scenario": os.path.join(HERE, RINGS[ring]["file"]),
                "out": os.path.join(args.out, "runs", name + ".h5"), "sets": sets}

    runs = []
    # Baselines first: FollowerStopper's U comes from them.
    base_jobs = [job(r, "baseline", 0, s, [f"seed={s}"]) for r in rings for s in seeds]
    runs += list(pool.map(run_one, base_jobs))
    base_speed = {r: float(np.mean([x["result"]["mean_speed"] for x in runs if x["ring"] == r])) for r in rings}
    jobs, U = [], {}
    for r in rings:
        n = RINGS[r]["n"]
        counts = sorted({av_count(n, share) for _, share in PENETRATIONS})
        for c, spec in CONTROLLERS.items():
            params = dict(spec["params"])
            if spec.get("U_from_baseline"):
                params["U_mps"] = round(base_speed[r], 3)
                U[r] = params["U_mps"]
            for n_av in counts:
                for s in seeds:
                    sets = [f"seed={s}", f"fleet.drivers[0].count={n - n_av}", f"fleet.drivers[1].count={n_av}",
                            f"fleet.drivers[1].model={spec['model']}"]
                    sets += [f"fleet.drivers[1].params.{k}={v}" for k, v in params.items()]
                    jobs.append(job(r, c, n_av, s, sets))
    done = 0
    for res in pool.map(run_one, jobs):
        runs.append(res)
        done += 1
        if done % 20 == 0:
            print(f"  {done}/{len(jobs)} controller runs ({time.time() - t0:.0f} s)", flush=True)
    pool.shutdown()
    wall = time.time() - t0
    agg = aggregate(runs, rings)
    write_h5(os.path.join(args.out, "sparse_control.h5"), runs, agg, rings, seeds, U, wall)
    md = markdown(agg, rings, seeds, U, wall)
    with open(os.path.join(args.out, "results.md"), "w") as f:
        f.write(md)
    plot(os.path.join(args.out, "sparse_control.png"), agg, rings)
    print(md)
    print(f"wrote {args.out}/sparse_control.h5, results.md, sparse_control.png ({len(runs)} runs, {wall:.0f} s)")


def aggregate(runs, rings):
    """Per (ring, controller, n_av): mean and s.d. over seeds of each metric, and of its relative change versus
    the baseline run with the same seed (paired, so the common noise cancels)."""
    base = {(x["ring"], x["seed"]): x["result"] for x in runs if x["controller"] == "baseline"}
    cases = {}
    for x in runs:
        cases.setdefault((x["ring"], x["controller"], x["n_av"]), []).append(x)
    agg = {}
    for key, xs in sorted(cases.items(), key=lambda kv: (kv[0][0], kv[0][1] != "baseline", kv[0][1], kv[0][2])):
        xs.sort(key=lambda x: x["seed"])
        a = {"n_seeds": len(xs)}
        for m, _, _ in METRICS + [("class_l_per_100km", "", "")]:
            vals = np.array([x["result"][m] for x in xs])
            b = np.array([base[(x["ring"], x["seed"])][m] for x in xs])
            # Relative change; undefined (NaN) where the baseline is 0 (overlaps, infeasible share on these rings).
            with np.errstate(divide="ignore", invalid="ignore"):
                rel = np.where(b != 0, 100.0 * (vals / np.where(b != 0, b, 1.0) - 1.0), np.nan)
            a[m] = (vals.mean(axis=0), vals.std(axis=0, ddof=1) if len(xs) > 1 else 0 * vals[0])
            a[m + "_change"] = (rel.mean(axis=0), rel.std(axis=0, ddof=1) if len(xs) > 1 else 0 * rel[0])
        a["class_names"] = xs[0]["result"]["class_names"]
        agg[key] = a
    return agg


def write_h5(path, runs, agg, rings, seeds, U, wall):
    tmp = path + ".partial"
    with h5py.File(tmp, "w") as f:
        f.attrs["description"] = "wavefuel sparse-control benchmark (bench/sparse_control/README.md)"
        f.attrs["seeds"] = np.array(seeds)
        f.attrs["wall_time_s"] = wall
        for r, u in U.items():
            f.attrs[f"follower_stopper_U_mps_{r}"] = u
        g = f.create_group("runs")
        str_cols = {"ring": [x["ring"] for x in runs], "controller": [x["controller"] for x in runs]}
        for k, v in str_cols.items():
            g.create_dataset(k, data=np.array(v, dtype=h5py.string_dtype())).attrs["units"] = "1"
        for k, unit in (("n_av", "1"), ("seed", "1")):
            g.create_dataset(k, data=np.array([x[k] for x in runs], dtype=np.int64)).attrs["units"] = unit
        for m, unit, desc in METRICS:
            d = g.create_dataset(m, data=np.array([x["result"][m] for x in runs]))
            d.attrs["units"], d.attrs["description"] = unit, desc
        ga = f.create_group("aggregate")
        keys = list(agg)
        for k, v in (("ring", [k[0] for k in keys]), ("controller", [k[1] for k in keys])):
            ga.create_dataset(k, data=np.array(v, dtype=h5py.string_dtype())).attrs["units"] = "1"
        ga.create_dataset("n_av", data=np.array([k[2] for k in keys], dtype=np.int64)).attrs["units"] = "1"
        for m, unit, desc in METRICS:
            for suffix, u2, what in (("", unit, desc), ("_change", "%", "relative change versus baseline, %")):
                for i, stat in enumerate(("mean", "sd")):
                    d = ga.create_dataset(f"{m}{suffix}_{stat}", data=np.array([agg[k][m + suffix][i] for k in keys]))
                    d.attrs["units"] = u2
                    d.attrs["description"] = f"{desc}{'' if not suffix else ': ' + what}, {stat} over seeds"
        for r in rings:
            gc = ga.create_group(f"class_{r}")
            rk = [k for k in keys if k[0] == r]
            gc.create_dataset("class", data=np.array(agg[rk[0]]["class_names"], dtype=h5py.string_dtype()))
            gc.create_dataset("controller", data=np.array([k[1] for k in rk], dtype=h5py.string_dtype()))
            gc.create_dataset("n_av", data=np.array([k[2] for k in rk], dtype=np.int64))
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


def markdown(agg, rings, seeds, U, wall):
    out = [f"Seeds {seeds[0]}..{seeds[-1]} per case; mean ± s.d. over seeds; changes are paired with the "
           f"baseline run of the same seed. Wall time {wall:.0f} s.\n"]
    for r in rings:
        n = RINGS[r]["n"]
        out.append(f"\n### {RINGS[r]['label']}: fleet\n")
        out.append(f"FollowerStopper U = {U[r]:.3f} m/s (the baseline's mean speed).\n")
        out.append("| controller | AVs | fuel L/100km | Δ fuel % | speed s.d. m/s | Δ s.d. % | braking /vkm "
                   "| stops /vkm | throughput veh/h | Δ thr. % | infeasible % | overlaps |")
        out.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for (ring, c, n_av), a in agg.items():
            if ring != r:
                continue
            pen = f"{n_av} ({100.0 * n_av / n:.1f} %)"
            out.append(
                f"| {c} | {pen} | {fmt(*a['l_per_100km'])} | {fmt(*a['l_per_100km_change'], 1)} "
                f"| {fmt(*a['sd_speed_time_avg'])} | {fmt(*a['sd_speed_time_avg_change'], 1)} "
                f"| {fmt(*a['hard_brakes_per_vkm'])} | {fmt(*a['stops_per_vkm'])} | {a['throughput'][0]:.0f} "
                f"| {fmt(*a['throughput_change'], 1)} | {100 * a['infeasible_share'][0]:.3f} "
                f"| {a['overlaps'][0]:.1f} |")
        names = next(a["class_names"] for k, a in agg.items() if k[0] == r)
        if len(names) > 1:
            out.append(f"\n### {RINGS[r]['label']}: fuel per class, L/100km (Δ % versus baseline)\n")
            out.append("| controller | AVs | " + " | ".join(names) + " |")
            out.append("|---|---|" + "---|" * len(names))
            for (ring, c, n_av), a in agg.items():
                if ring != r:
                    continue
                cells = [f"{a['class_l_per_100km'][0][i]:.2f} ({a['class_l_per_100km_change'][0][i]:+.1f})"
                         for i in range(len(names))]
                out.append(f"| {c} | {n_av} | " + " | ".join(cells) + " |")
    if "sugiyama" in rings:
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
            out.append(f"| {c} (U = {U['sugiyama']:.2f} m/s) | wavefuel | " if c == "follower_stopper" else
                       f"| {c} | wavefuel | ")
            out[-1] += (f"{a['sd_speed_time_avg_change'][0]:+.1f} | {a['l_per_100km_change'][0]:+.1f} "
                        f"| {base['hard_brakes_per_vkm'][0]:.2f} → {a['hard_brakes_per_vkm'][0]:.2f} "
                        f"({brk:+.1f} %) | {a['throughput_change'][0]:+.1f} |")
    return "\n".join(out) + "\n"


def plot(path, agg, rings):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(2, len(rings), figsize=(5.5 * len(rings), 7), squeeze=False)
    for j, r in enumerate(rings):
        n = RINGS[r]["n"]
        for c in CONTROLLERS:
            ks = sorted(k for k in agg if k[0] == r and k[1] == c)
            x = [100.0 * k[2] / n for k in ks]
            for i, m in enumerate(("l_per_100km_change", "sd_speed_time_avg_change")):
                mean = [agg[k][m][0] for k in ks]
                sd = [agg[k][m][1] for k in ks]
                ax[i][j].errorbar(x, mean, yerr=sd, marker="o", capsize=3, label=c)
        ax[0][j].set_title(RINGS[r]["label"])
        ax[0][j].set_ylabel("fleet fuel change vs baseline (%)")
        ax[1][j].set_ylabel("speed s.d. change vs baseline (%)")
        ticks = sorted({100.0 * k[2] / n for k in agg if k[0] == r and k[2] > 0})
        for i in range(2):
            ax[i][j].axhline(0.0, color="grey", lw=0.8)
            ax[i][j].set_xscale("log")
            ax[i][j].set_xticks(ticks, [f"{t:.2g}" for t in ticks])
            ax[i][j].minorticks_off()
            ax[i][j].set_xlabel("AV penetration (% of vehicles)")
            ax[i][j].grid(alpha=0.3)
        ax[0][j].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    main()
