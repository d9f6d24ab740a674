#!/usr/bin/python3
"""Two or more wavefuel binaries side by side on the scaling ring (bench/scaling/ring.yaml: IDM with noise, two
energy classes, ballistic dt 0.1 s, a record every second, 25 m of road per vehicle), the binaries alternating
within each repeat so that all meet the same load. Vehicle-steps per second of the step loop
(N x /meta/steps_done / /meta/wall_time_s), best and median of --repeats, with the 1-minute load average.

Each binary is copied first (a rebuild during the runs cannot mix versions) and finds the checkout's vehicle
classes through WAVEFUEL_VEHICLES. A NAME=PATH may carry environment settings after a comma, e.g.
--bin narrow=bin/wavefuel,WAVEFUEL_SIMD=4 (the hand-written kernels capped at 4 lanes, docs/energy.md).

With --steady the rate is that of the steps after the first: each case runs steps_for(N) steps and five times as
many, and the rate is N x (the difference of the steps) / (the difference of the loops' wall times): what the first
steps pay once cancels (before 1aa3996, some 2-3 s of page faults of the step's 2 GB of arrays at 10^7 vehicles, which
a ring now takes at its creation: src/util/mem.h).

Usage: /usr/bin/python3 bench/ab/run.py --bin old=/tmp/wavefuel_old --bin new=bin/wavefuel
           [--sizes 100000,1000000,10000000] [--threads 1,2] [--repeats 3] [--steady] [--json FILE]
"""
import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile

import h5py

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SCENARIO = os.path.join(ROOT, "bench", "scaling", "ring.yaml")


def steps_for(n):
    """About 1.6e8 vehicle-steps per run, in whole windows of 16 steps (the default before session 23), at least 48."""
    return max(48, int(1.6e8 / n) // 16 * 16)


def loop_time(binary, env, n, threads, steps, tmp):
    """(steps done, wall time of the step loop) of one run of `steps` steps."""
    out = os.path.join(tmp, "r.h5")
    cmd = [binary, "run", SCENARIO, "-q", "-o", out, "--threads", str(threads),
           "--set", f"fleet.vehicles={n}", "--set", f"road.length_m={25 * n}",
           "--set", f"time.duration_s={steps / 10:g}"]
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if p.returncode:
        sys.exit(f"{' '.join(cmd)} failed: {p.stderr}")
    with h5py.File(out) as f:
        done, wall = int(f["meta/steps_done"][()]), float(f["meta/wall_time_s"][()])
    os.unlink(out)
    return done, wall


def one_run(binary, env, n, threads, tmp, steady):
    """Vehicle-steps per second of the step loop; steady: of the steps between a run of steps_for(n) steps and one of
    five times as many (the difference of the two loops' times: what the first steps pay once, the first touch of
    the arrays the step writes, cancels)."""
    s1 = steps_for(n)
    d1, w1 = loop_time(binary, env, n, threads, s1, tmp)
    if not steady:
        return n * d1 / w1
    d2, w2 = loop_time(binary, env, n, threads, 5 * s1, tmp)
    return n * (d2 - d1) / (w2 - w1)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", action="append", required=True, help="NAME=PATH[,VAR=VALUE...] (repeatable)")
    ap.add_argument("--sizes", default="100000,1000000,10000000")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", help="write every run here")
    ap.add_argument("--steady", action="store_true",
                    help="the rate of the steps after the first steps_for(N) (runs of 1 and 5 times as many)")
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="wf_ab_")
    bins = []
    for k, spec in enumerate(a.bin):
        name, rest = spec.split("=", 1)
        path, *sets = rest.split(",")
        copy = os.path.join(tmp, f"wavefuel{k}")
        shutil.copy(path, copy)
        env = dict(os.environ, WAVEFUEL_VEHICLES=os.path.join(ROOT, "vehicles"))
        env.update(s.split("=", 1) for s in sets)
        bins.append((name, copy, env))
    sizes = [int(s) for s in a.sizes.split(",")]
    threads = [int(t) for t in a.threads.split(",")]
    runs = []
    try:
        for _ in range(a.repeats):
            for n in sizes:
                for th in threads:
                    for name, copy, env in bins:
                        rate = one_run(copy, env, n, th, tmp, a.steady)
                        runs.append({"bin": name, "n": n, "threads": th, "rate": rate, "load": os.getloadavg()[0]})
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(runs, f, indent=1)
    names = [b[0] for b in bins]
    print("| N | threads | " + " | ".join(f"{nm} best (median)" for nm in names) +
          f" | {names[-1]} / {names[0]} (best) | load |")
    print("|---|---|" + "---|" * len(names) + "---|---|")
    for n in sizes:
        for th in threads:
            rs = {nm: [r["rate"] for r in runs if r["bin"] == nm and r["n"] == n and r["threads"] == th]
                  for nm in names}
            loads = [r["load"] for r in runs if r["n"] == n and r["threads"] == th]
            cells = " | ".join(f"{max(rs[nm]):.3g} ({statistics.median(rs[nm]):.3g})" for nm in names)
            print(f"| {n:.0e} | {th} | {cells} | {max(rs[names[-1]]) / max(rs[names[0]]):.2f} | "
                  f"{min(loads):.1f}–{max(loads):.1f} |")


if __name__ == "__main__":
    main()
