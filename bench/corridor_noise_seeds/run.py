#!/usr/bin/env python3
"""Corridor noise realisations (issue 16): the summaries of a corridor scenario over seeds 1..N for each binary
given, as mean ± s.d. across seeds, and for each summary how far the means of two binaries are apart in units of
the first binary's seed-to-seed s.d. Used to show that the corridor's vectorised noise (keyed by slot block and
step) changes results only as a new noise realisation would.

usage: run.py --bin old=/tmp/wavefuel_main --bin new=bin/wavefuel [--scenario scenarios/corridor_bottleneck.yaml]
              [--seeds 10] [--threads 2] [--set key=value]..."""
import argparse
import os
import subprocess
import tempfile

import h5py
import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "../.."))
KEYS = [("fuel", "g"), ("l_per_100km", "L/100km"), ("mean_speed", "m/s"), ("sd_speed_time_avg", "m/s"),
        ("outflow", "veh/h")]


def summaries(binary, scenario, seed, threads, sets, tmp):
    out = os.path.join(tmp, "s.h5")
    cmd = [binary, "run", scenario, "-o", out, "--force", "-q", "--threads", str(threads), "--set", "seed=%d" % seed,
           "--set", "output.trajectories=false"]
    for s in sets:
        cmd += ["--set", s]
    subprocess.run(cmd, check=True)
    with h5py.File(out, "r") as f:
        return [float(np.asarray(f["summary/" + k][()]).ravel()[0]) for k, _ in KEYS]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", action="append", required=True, help="NAME=PATH (repeatable; the first is the reference)")
    ap.add_argument("--scenario", default=os.path.join(ROOT, "scenarios/corridor_bottleneck.yaml"))
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--set", action="append", default=[])
    args = ap.parse_args()
    res = {}
    with tempfile.TemporaryDirectory() as tmp:
        for b in args.bin:
            name, path = b.split("=", 1)
            res[name] = np.array([summaries(path, args.scenario, s, args.threads, args.set, tmp)
                                  for s in range(1, args.seeds + 1)])
    names = list(res)
    print("| summary | " + " | ".join("%s (mean ± s.d., %d seeds)" % (n, args.seeds) for n in names) +
          " | |mean difference| / s.d. of %s |" % names[0])
    print("|---|" + "---|" * (len(names) + 1))
    for j, (k, unit) in enumerate(KEYS):
        ref = res[names[0]][:, j]
        cells = ["%.6g ± %.3g" % (res[n][:, j].mean(), res[n][:, j].std(ddof=1)) for n in names]
        diffs = ", ".join("%.2f" % (abs(res[n][:, j].mean() - ref.mean()) / ref.std(ddof=1)) for n in names[1:])
        print("| %s (%s) | %s | %s |" % (k, unit, " | ".join(cells), diffs))


if __name__ == "__main__":
    main()
