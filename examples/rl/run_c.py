#!/usr/bin/env python3
"""Exports a trained policy (train.py's policy.pt) as a `model: mlp` network file and runs it in C with
`wavefuel run`: on the Sugiyama ring (scenarios/sugiyama.yaml, its vehicle 0 driven by the network) and on the
corridor bottleneck (scenarios/corridor_bottleneck.yaml, a share of the entering vehicles driven by it), each
against the shipped all-human scenario and the same AVs as `acc`. The derived scenarios, results and figures go
to the output directory (the shipped files are not touched). Checks first that the library's evaluation of the
network equals the PyTorch policy's mean action (float64, within 1e-12) on observations met in the runs and on
random ones, and that the accelerations the AV drove in a run are that action on the rows it observed.

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
    (vehicle 0), on a corridor a share av_share of the entering vehicles. Relative paths made absolute."""
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
    sim = wavefuel.Simulation(wavefuel.Scenario.load(scenario_path), threads=1)
    av = sim.scenario.groups.index("av")
    rows, driven = [], []
    for _ in range(steps):
        obs = sim.observe("av")
        sim.step(1)
        st = sim.state()
        rows.append(obs)
        driven.append(np.array(st["a_mps2"][st["group_id"] == av]))
    sim.close()
    rows, driven = np.concatenate(rows), np.concatenate(driven)
    return float(np.max(np.abs(driven - policy.act(rows)))), rows


def run(bin_, scenario, out):
    p = subprocess.run([bin_, "run", scenario, "-o", out, "--force", "-q"], capture_output=True, text=True)
    if p.returncode:
        raise SystemExit(f"wavefuel run {scenario}: {p.stderr.strip()}")
    r = wavefuel.read(out)
    keys = ("fuel", "l_per_100km", "mean_speed", "stops_per_vkm", "hard_brakes_per_vkm", "vkt", "overlaps")
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
        checks[f"{road}: driven accelerations vs torch ({len(rows)} rows)"] = d_run
        checks[f"{road}: library network vs torch on the observed rows"] = check_network(policy, network, rows)
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
          f"{'vs human':>8s}")
    for (road, model), r in results.items():
        h = results[(road, "human")]
        label = {"human": "all human", "acc": "AVs acc", "mlp": "AVs policy"}[model]
        print(f"{road:9s} {label:14s} {r['fuel']:10.1f} {r['l_per_100km']:8.3f} {r['mean_speed']:9.3f} "
              f"{r['stops_per_vkm']:9.3f} {100 * (1 - r['l_per_100km'] / h['l_per_100km']):7.2f}%")
    with open(out("run_c.json"), "w") as f:
        json.dump({"checks": checks, "results": {f"{k[0]}_{k[1]}": v for k, v in results.items()}}, f, indent=1)
    figures(args.output, results)


def figures(outdir, results):
    """Time-space diagrams of every run (tools/plot_timespace.py, plot_corridor.py), and rl_c.png: side by side,
    the ring's all-human and policy runs."""
    tools = os.path.join(REPO, "tools")
    for (road, model) in results:
        h5 = os.path.join(outdir, f"{road}_{model}.h5")
        tool = "plot_timespace.py" if road == "ring" else "plot_corridor.py"
        p = subprocess.run([sys.executable, os.path.join(tools, tool), h5, "--vmax", "30" if road != "ring" else "10"],
                           capture_output=True, text=True)
        print(p.stdout.strip() or p.stderr.strip())


if __name__ == "__main__":
    main()
