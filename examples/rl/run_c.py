#!/usr/bin/env python3
"""Exports a trained policy (train.py's policy.pt) as a `model: mlp` network file and runs it in C with
`wavefuel run`: on the Sugiyama ring (scenarios/sugiyama.yaml, one of its vehicles driven by the network) and on the
corridor bottleneck (scenarios/corridor_bottleneck.yaml, a share of the entering vehicles driven by it), each
against the shipped all-human scenario and the same AVs as `acc`. The derived scenarios, results and figures go
to the output directory (the shipped files are not touched). Checks first that the library's evaluation of the
network equals the PyTorch policy's mean action (float64, within 1e-12) on observations met in the runs and on
random ones, and that the accelerations the AV drove on the ring are that action on the rows it observed.

    PYTHONPATH=python /usr/bin/python3 examples/rl/run_c.py output/rl/policy.pt -o output/rl
"""
import argparse
import json
import os
import subprocess
import sys

import numpy as np
import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from platoon import REPO  # noqa: E402

import wavefuel  # noqa: E402

TOL = 1e-12


def derived(shipped, network, av_share, model, out_path):
    """The shipped scenario with an AV group of `model` (mlp with `network`, or acc): on a ring one vehicle
    (placed by the scenario's placement), on a corridor a share av_share of the entering vehicles. Relative paths
    made absolute."""
    with open(shipped) as f:
        d = yaml.safe_load(f)
    base = os.path.dirname(os.path.abspath(shipped))
    if "inflow" in d.get("corridor", {}) and "csv" in d["corridor"]["inflow"]:
        d["corridor"]["inflow"]["csv"] = os.path.join(base, d["corridor"]["inflow"]["csv"])
    human = d["fleet"]["drivers"][0]
    av = {"name": "av", "model": model}
    if model == "mlp":
        av["network"] = os.path.abspath(network)
    if d["road"].get("type", "ring") == "ring":
        human.pop("fraction", None)
        human["count"] = d["fleet"]["vehicles"] - 1
        av["count"] = 1
    else:
        human["fraction"] = 1.0 - av_share
        av["fraction"] = av_share
    d["fleet"]["drivers"].append(av)
    d["name"] = f"{d['name']}_{model}"
    with open(out_path, "w") as f:
        json.dump(d, f, indent=1)  # JSON is YAML
    return out_path


def check_network(policy, path, rows):
    """Max |library - torch| over rows: the network file evaluated by the library, the policy's mean action."""
    c = wavefuel.Network(path).evaluate(rows)
    return float(np.max(np.abs(c - policy.act(rows))))


def check_in_run(policy, scenario_path, steps):
    """A Python run of a derived scenario for `steps` steps: before each, the rows the network gets
    (sim.observe); after it, the accelerations the AVs drove (the state's a_mps2, the value at the step's start:
    the command, the AVs having no noise and the commands staying inside the limits). Returns max |driven - torch
    action| and the rows."""
    # fused_step false: the state keeps every vehicle's acceleration of the last step (docs/python.md).
    sim = wavefuel.Simulation(wavefuel.Scenario.load(scenario_path, {"time.fused_step": "false"}), threads=1)
    av = sim.scenario.groups.index("av")

    def avs():
        """Identities (corridor: arrival serials; ring: indices) and state of the AVs, in road order."""
        st = sim.state()
        m = st["group_id"] == av
        return (st["serial"] if "serial" in st else np.arange(m.size))[m], st, m
    rows, driven = [], []
    for _ in range(steps):
        ids0, _, _ = avs()
        obs = sim.observe("av")
        sim.step(1)
        ids1, st, m = avs()
        # AVs on the road before and after the step (a corridor's vehicles enter and leave).
        both, i0, i1 = np.intersect1d(ids0, ids1, return_indices=True)
        rows.append(obs[i0])
        driven.append(np.array(st["a_mps2"][m][i1]))
    sim.close()
    rows, driven = np.concatenate(rows), np.concatenate(driven)
    return float(np.max(np.abs(driven - policy.act(rows)))), rows


def run(bin_, scenario, out):
    p = subprocess.run([bin_, "run", scenario, "-o", out, "--force", "-q"], capture_output=True, text=True)
    if p.returncode:
        raise SystemExit(f"wavefuel run {scenario}: {p.stderr.strip()}")
    r = wavefuel.read(out)
    keys = ("fuel", "l_per_100km", "mean_speed", "stops_per_vkm", "hard_brakes_per_vkm", "vkt", "overlaps",
            "mean_travel_time", "mean_trip_fuel")
    return {k: float(r[f"summary/{k}"]) for k in keys if f"summary/{k}" in r}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("policy", help="train.py's policy.pt")
    ap.add_argument("-o", "--output", required=True, help="directory for the network, scenarios, results, figures")
    ap.add_argument("--bin", default=os.path.join(REPO, "bin", "wavefuel"), help="wavefuel (default ./bin/wavefuel)")
    ap.add_argument("--share", type=float, default=0.1, help="corridor: share of AVs among entering vehicles "
                                                               "(default 0.1)")
    args = ap.parse_args()
    from policy import export, load  # torch only here
    policy, _ = load(args.policy)
    os.makedirs(args.output, exist_ok=True)
    out = lambda name: os.path.join(args.output, name)  # noqa: E731
    network = export(policy, out("policy_mlp.h5"))
    print(f"network: {network}")

    shipped = {"ring": os.path.join(REPO, "scenarios", "sugiyama.yaml"),
               "corridor": os.path.join(REPO, "scenarios", "corridor_bottleneck.yaml")}
    scen = {(road, model): derived(path, network, args.share, model, out(f"{road}_{model}.yaml"))
            for road, path in shipped.items() for model in ("mlp", "acc")}

    # The library's network against the torch policy.
    rng = np.random.default_rng(0)
    v = rng.uniform(0, 35, 100000)
    rand = np.column_stack([v, np.maximum(v + rng.normal(0, 3, v.size), 0), rng.uniform(0, 150, v.size)])
    checks = {}
    for road, steps in (("ring", 6000), ("corridor", 3000)):
        d_run, rows = check_in_run(policy, scen[(road, "mlp")], steps)
        if road == "ring":
            checks[f"{road}: accelerations driven in the run vs torch ({len(rows)} rows)"] = d_run
        else:  # the road's speed limit and work zone also bound what a corridor's vehicles drive
            print(f"corridor: accelerations driven differ from the network's commands by up to {d_run:.3g} m/s^2 "
                  f"(the road's speed limits)")
        checks[f"{road}: library network vs torch on the {len(rows)} rows observed"] = check_network(policy, network,
                                                                                                     rows)
    checks["random rows (100000): library network vs torch"] = check_network(policy, network, rand)
    for k, d in checks.items():
        print(f"{'ok ' if d <= TOL else 'BAD'} max |difference| {d:.3g} m/s^2: {k}")
    if max(checks.values()) > TOL:
        raise SystemExit(f"the C controller differs from the torch policy by more than {TOL}")

    results = {}
    for road, path in shipped.items():
        results[(road, "human")] = run(args.bin, path, out(f"{road}_human.h5"))
        for model in ("acc", "mlp"):
            results[(road, model)] = run(args.bin, scen[(road, model)], out(f"{road}_{model}.h5"))
    print(f"{'road':9s} {'drivers':14s} {'fuel g':>10s} {'L/100km':>8s} {'speed m/s':>9s} {'stops/vkm':>9s} "
          f"{'overlaps':>8s} {'vs human':>8s}")
    for (road, model), r in results.items():
        h = results[(road, "human")]
        label = {"human": "all human", "acc": "AVs acc", "mlp": "AVs policy"}[model]
        print(f"{road:9s} {label:14s} {r['fuel']:10.1f} {r['l_per_100km']:8.3f} {r['mean_speed']:9.3f} "
              f"{r['stops_per_vkm']:9.3f} {r['overlaps']:8.0f} {100 * (1 - r['l_per_100km'] / h['l_per_100km']):7.2f}%")
    with open(out("run_c.json"), "w") as f:
        json.dump({"checks": checks, "results": {f"{k[0]}_{k[1]}": v for k, v in results.items()}}, f, indent=1)
    figures(args.output, results, args.share)


def figures(outdir, results, share):
    """Time-space diagrams of every run (tools/plot_timespace.py, plot_corridor.py: large), and the small summary
    figure rl_c.png: the ring's AV (a human in the all-human run) and the vehicle opposite it over time, and
    L/100km of every run."""
    tools = os.path.join(REPO, "tools")
    for (road, model) in results:
        h5 = os.path.join(outdir, f"{road}_{model}.h5")
        tool = "plot_timespace.py" if road == "ring" else "plot_corridor.py"
        p = subprocess.run([sys.executable, os.path.join(tools, tool), h5, "--vmax", "30" if road != "ring" else "10"],
                           capture_output=True, text=True)
        print(p.stdout.strip() or p.stderr.strip())
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 3.4), gridspec_kw={"width_ratios": [2, 1]})
    colours = {"human": "tab:red", "acc": "tab:blue", "mlp": "tab:green"}
    labels = {"human": "all human", "acc": "AV acc", "mlp": "AV policy"}
    r = wavefuel.read(os.path.join(outdir, "ring_mlp.h5"))
    k_av = int(np.flatnonzero(r["vehicles/group_id"] == list(r["drivers/name"]).index("av"))[0])
    k_h = (k_av + r["vehicles/group_id"].size // 2) % r["vehicles/group_id"].size  # the vehicle opposite it
    for model in ("human", "mlp"):
        r = wavefuel.read(os.path.join(outdir, f"ring_{model}.h5"))
        t, v = r["trajectories/t"], r["trajectories/v"]
        ax0.plot(t, v[:, k_av], color=colours[model], lw=1.0,
                 label=f"{labels[model]}: vehicle {k_av}" + (" (the AV)" if model != "human" else ""))
        ax0.plot(t, v[:, k_h], color=colours[model], lw=0.6, ls=":", label=f"{labels[model]}: vehicle {k_h} (human)")
    ax0.set(title="Sugiyama ring (22 vehicles, 230 m): speeds", xlabel="time (s)", ylabel="speed (m/s)")
    ax0.legend(fontsize=7, ncol=2, loc="upper right")
    roads = ("ring", "corridor")
    for k, model in enumerate(("human", "acc", "mlp")):
        vals = [100 * results[(road, model)]["l_per_100km"] / results[(road, "human")]["l_per_100km"] for road in roads]
        ax1.bar(np.arange(2) + (k - 1) * 0.27, vals, 0.27, color=colours[model], label=labels[model])
    ticks = ["Sugiyama ring\n1 AV of 22", f"corridor bottleneck\n{100 * share:g} % AVs"]
    ax1.set(xticks=range(2), xticklabels=ticks, ylabel="L/100km, % of all human", ylim=(85, 102),
            title="fuel per distance")
    ax1.legend(fontsize=7)
    fig.tight_layout()
    path = os.path.join(outdir, "rl_c.png")
    fig.savefig(path, dpi=80)
    print(path)


if __name__ == "__main__":
    main()
