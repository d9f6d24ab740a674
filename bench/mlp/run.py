#!/usr/bin/env python3
"""Cost of the MLP controller (`model: mlp`) per vehicle-step (issue 17): a ring of N vehicles all driven by a 2 x 64
tanh network, against the same ring all driven by the built-in `acc` law that the network was fitted to, with 1 and
2 threads, best of R repeats; and the network alone (wavefuel.Network.evaluate on N rows, the code a run calls once
per step). The network: two random tanh layers of 64 units and a least-squares output layer fitted to acc's
acceleration (examples/mlp/make_policy.py's fit), so both rings carry similar traffic.

    /usr/bin/python3 bench/mlp/run.py [--vehicles 10000] [--steps 200] [--repeats 3]

Prints the machine, the table of bench/README.md ("MLP controller") and one BENCH line per configuration.
Needs bin/wavefuel and lib/libwavefuel.so (`make all python`)."""
import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "python"))
sys.path.insert(0, os.path.join(ROOT, "examples", "mlp"))
import wavefuel  # noqa: E402
from make_policy import fit  # noqa: E402

# acc's defaults (docs/controllers.md)
K_GAP, K_DV, T_S, S0_M, V0_MPS, K_V = 0.4, 0.8, 1.1, 2.0, 30.0, 0.4
SPACING_M = 25.0  # ring length per vehicle: gap 20.5 m, acc's uniform flow at 16.8 m/s


def acc_law(v, vl, gap):
    return np.minimum(K_GAP * (gap - S0_M - T_S * v) + K_DV * (vl - v), K_V * (V0_MPS - v))


def scenario(path, n, steps, model, network):
    driver = f"{{name: av, model: {model}, fraction: 1.0" + (f", network: {network}}}" if network else "}")
    with open(path, "w") as f:
        f.write(f"""name: bench_mlp
seed: 1
road: {{length_m: {n * SPACING_M}}}
time: {{duration_s: {steps * 0.1:.1f}, dt_s: 0.1, output_interval_s: {steps * 0.1:.1f}, warmup_s: 0}}
fleet:
  vehicles: {n}
  classes: [{{class: midsize_sedan, fraction: 1.0}}]
  drivers: [{driver}]
initial: {{state: equilibrium, jitter_m: 0.5}}
output: {{trajectories: false}}
""")


def run(tmp, yaml, threads):
    out = os.path.join(tmp, "out.h5")
    subprocess.run([os.path.join(ROOT, "bin", "wavefuel"), "run", yaml, "-o", out, "--force", "-q",
                    "--threads", str(threads)], check=True)
    with h5py.File(out, "r") as f:
        return float(f["meta/wall_time_s"][()]), int(f["summary/overlaps"][()])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--vehicles", type=int, default=10000)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args()
    load = os.getloadavg()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, load "
          f"{load[0]:.2f} at start, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    with tempfile.TemporaryDirectory() as tmp:
        layers, rows, y, mean = fit(acc_law, hidden=(64, 64), seed=17, v_max_mps=25.0, gap_max_m=40.0)
        net = os.path.join(tmp, "acc_2x64.h5")
        wavefuel.export_mlp(net, layers, activations="tanh", input_mean=mean, input_std=mean, output_min=-9.0,
                            output_max=5.0)
        err = wavefuel.mlp_forward(net, rows) - np.clip(y, -9.0, 5.0)
        print(f"network: 3 -> 64 -> 64 -> 1 tanh fitted to acc (speeds in [0, 25] m/s, gaps in [0, 40] m), output "
              f"clipped to [-9, 5] m/s^2: rms error {np.sqrt(np.mean(err ** 2)):.3f} m/s^2")
        yamls = {}
        for model in ("acc", "mlp"):
            yamls[model] = os.path.join(tmp, f"{model}.yaml")
            scenario(yamls[model], a.vehicles, a.steps, model, net if model == "mlp" else None)
        vs = a.vehicles * a.steps
        res = {}
        for threads in (1, 2):
            for model in ("acc", "mlp"):
                best, overlaps = min(run(tmp, yamls[model], threads) for _ in range(a.repeats))
                res[model, threads] = best
                print(f"BENCH mlp ring model={model} threads={threads} vehicles={a.vehicles} steps={a.steps} "
                      f"best_s={best:.4f} ns_per_vehicle_step={best / vs * 1e9:.1f} overlaps={overlaps}")
            x = rows[:a.vehicles]
            with wavefuel.Network(net) as nw:
                best = min(timed(nw, x, threads) for _ in range(a.repeats * 5))
            res["eval", threads] = best
            print(f"BENCH mlp eval threads={threads} rows={a.vehicles} best_s={best:.6f} "
                  f"ns_per_row={best / a.vehicles * 1e9:.1f}")
        print(f"\n| ns per vehicle-step ({a.vehicles} vehicles, {a.steps} steps) | 1 thread | 2 threads |")
        print("|---|---|---|")
        for label, key in (("ring, all `acc`", "acc"), ("ring, all `mlp` (2 x 64 tanh)", "mlp")):
            print(f"| {label} | {res[key, 1] / vs * 1e9:.0f} | {res[key, 2] / vs * 1e9:.0f} |")
        print(f"| difference: the MLP controller | {(res['mlp', 1] - res['acc', 1]) / vs * 1e9:.0f} | "
              f"{(res['mlp', 2] - res['acc', 2]) / vs * 1e9:.0f} |")
        print(f"| the network alone (`Network.evaluate`, {a.vehicles} rows) | "
              f"{res['eval', 1] / a.vehicles * 1e9:.0f} | {res['eval', 2] / a.vehicles * 1e9:.0f} |")


def timed(nw, x, threads):
    t0 = time.perf_counter()
    nw.evaluate(x, threads=threads)
    return time.perf_counter() - t0


if __name__ == "__main__":
    main()
