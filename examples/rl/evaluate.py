#!/usr/bin/env python3
"""Evaluates a trained policy (train.py's policy.pt) on held-out traces: the platoon's fuel (g, L/100km; the AVs
and the humans behind them, platoon.py) with the policy's deterministic action in the AVs, against all-human
driving (the AVs replaced by the IDM humans) and against `acc` (the AVs without commands), on the same scenario
and seed (the humans' noise). Prints a table, writes DIR/evaluation.json and the figure DIR/evaluation.png.

    PYTHONPATH=python /usr/bin/python3 examples/rl/evaluate.py output/rl/policy.pt -o output/rl
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import platoon  # noqa: E402
from platoon import HELDOUT_TRACES, Episode, PlatoonEnv, l_per_100km, load_trace  # noqa: E402

CONTROLLERS = ("human", "acc", "policy")


def run(trace, seed, controller, act=None):
    """(fuel g, distance m, record [(t, speeds)]) of the platoon on one trace."""
    env = PlatoonEnv(trace, humans_only=controller == "human")
    ep = Episode(env, seed)
    record = []
    while not ep.done:
        ep.step(act(ep.obs) if controller == "policy" else None, count_fuel=True, record=record)
    fuel, dist = ep.platoon_totals()
    first = int(ep.av_index[0])
    ep.close()
    return fuel, dist, record, first


def figure(path, traces_shown):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(len(traces_shown), 2, figsize=(12, 3.2 * len(traces_shown)), squeeze=False)
    colours = {"human": "tab:red", "acc": "tab:blue", "policy": "tab:green"}
    for row, (name, rec) in zip(axes, traces_shown):
        for c in CONTROLLERS:
            t = np.array([r[0] for r in rec[c]["record"]])
            v = np.array([r[1] for r in rec[c]["record"]])
            row[0].plot(t, v[:, -1], color=colours[c], lw=0.8, label=f"{c}: last vehicle")
            fuel = np.array([r[2] for r in rec[c]["record"]])
            row[1].plot(t, fuel / 1e3, color=colours[c], lw=1.0,
                        label=f"{c}: {rec[c]['fuel_g']:.0f} g, {rec[c]['l_per_100km']:.3f} L/100km")
        t = np.array([r[0] for r in rec["human"]["record"]])
        v = np.array([r[1] for r in rec["human"]["record"]])
        row[0].plot(t, v[:, 0], color="0.5", lw=0.8, ls="--", label="front vehicle (human)")
        row[0].set(title=f"{name} (held out): speeds", xlabel="time (s)", ylabel="speed (m/s)")
        row[1].set(title=f"{name}: platoon fuel ({rec['human']['n']} vehicles)", xlabel="time (s)",
                   ylabel="cumulative fuel (kg)")
        row[0].legend(fontsize=7, loc="upper right")
        row[1].legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=70)
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("policy", help="train.py's policy.pt")
    ap.add_argument("-o", "--output", required=True, help="directory for evaluation.json and evaluation.png")
    ap.add_argument("--data", default=platoon.default_data_dir(),
                    help="data directory holding cycles/*.csv (default $WAVEFUEL_DATA, else ../shared/data "
                         "next to the repository)")
    ap.add_argument("--traces", default=",".join(HELDOUT_TRACES), help="traces (default %(default)s)")
    ap.add_argument("--seeds", default="1,2,3", help="episode seeds: the humans' noise (default %(default)s)")
    ap.add_argument("--horizon-s", type=float, default=None, help="evaluate the first seconds of each trace only")
    ap.add_argument("--figure-traces", type=int, default=2, help="traces drawn, seed 1 (default 2)")
    args = ap.parse_args()
    from policy import load  # torch only here
    policy, info = load(args.policy)
    trained_on = set(info["traces"])
    os.makedirs(args.output, exist_ok=True)
    seeds = [int(s) for s in args.seeds.split(",")]
    rows, shown = [], []
    total = {c: [0.0, 0.0] for c in CONTROLLERS}
    print(f"{'trace':16s} {'seed':>4s} " + " ".join(f"{c + ' g':>10s} {'L/100km':>8s}" for c in CONTROLLERS)
          + f" {'vs human':>9s} {'vs acc':>8s}")
    for name in args.traces.split(","):
        if name in trained_on:
            print(f"warning: {name} was a training trace", file=sys.stderr)
        trace = load_trace(name, args.data)
        if args.horizon_s:
            keep = trace[0] <= args.horizon_s
            trace = (trace[0][keep], trace[1][keep])
        for seed in seeds:
            rec = {}
            for c in CONTROLLERS:
                fuel, dist, record, first = run(trace, seed, c, policy.act)
                rec[c] = {"fuel_g": fuel, "dist_m": dist, "l_per_100km": l_per_100km(fuel, dist),
                          "record": record, "n": platoon.N_VEHICLES - first}
                total[c][0] += fuel
                total[c][1] += dist
            if seed == seeds[0] and len(shown) < args.figure_traces:
                shown.append((name, rec))
            f = {c: rec[c]["fuel_g"] for c in CONTROLLERS}
            row = {"trace": name, "seed": seed,
                   **{f"{c}_{k}": rec[c][k] for c in CONTROLLERS for k in ("fuel_g", "dist_m", "l_per_100km")}}
            rows.append(row)
            print(f"{name:16s} {seed:4d} "
                  + " ".join(f"{rec[c]['fuel_g']:10.1f} {rec[c]['l_per_100km']:8.3f}" for c in CONTROLLERS)
                  + f" {100 * (1 - f['policy'] / f['human']):8.2f}% {100 * (1 - f['policy'] / f['acc']):7.2f}%",
                  flush=True)
    tot = {c: {"fuel_g": v[0], "dist_m": v[1], "l_per_100km": l_per_100km(*v)} for c, v in total.items()}
    saved_h = 100 * (1 - tot["policy"]["fuel_g"] / tot["human"]["fuel_g"])
    saved_a = 100 * (1 - tot["policy"]["fuel_g"] / tot["acc"]["fuel_g"])
    lh = 100 * (1 - tot["policy"]["l_per_100km"] / tot["human"]["l_per_100km"])
    print(f"{'all':16s} {'':4s} " + " ".join(f"{tot[c]['fuel_g']:10.1f} {tot[c]['l_per_100km']:8.3f}"
                                             for c in CONTROLLERS) + f" {saved_h:8.2f}% {saved_a:7.2f}%")
    print(f"policy against all-human: {saved_h:.2f} % less fuel (g), {lh:.2f} % fewer L/100km; against acc: "
          f"{saved_a:.2f} % less fuel (g)")
    with open(os.path.join(args.output, "evaluation.json"), "w") as fh:
        json.dump({"rows": rows, "total": tot, "saved_vs_human_pct": saved_h, "saved_vs_acc_pct": saved_a,
                   "l_per_100km_saved_vs_human_pct": lh, "policy": os.path.abspath(args.policy),
                   "training": {k: info.get(k) for k in ("traces", "iterations", "wall_s", "load_start",
                                                         "load_end")}}, fh, indent=1)
    if shown:
        print(figure(os.path.join(args.output, "evaluation.png"), shown))


if __name__ == "__main__":
    main()
