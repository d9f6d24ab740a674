#!/usr/bin/python3
"""Time-blocked stepping (issue 20): the ring of bench/scaling/ring.yaml (IDM with noise, two energy classes,
ballistic dt 0.1 s, a record every second, 25 m of road per vehicle) stepped one step at a time
(time.block_steps: 1) and in windows (the default, 64 steps), side by side in one run.

For each N and thread count, the two modes alternate within each repeat (so both meet the same load); the tables give
the best of --repeats as vehicle-steps per second of the step loop (N x /meta/steps_done / /meta/wall_time_s), the
peak RSS per vehicle (GNU time %M) and the 1-minute load average. With --load, the same runs with two CPU-bound
processes beside them (busy loops that stop themselves after --load-timeout seconds, and are killed at the end): on
this 2-core machine each of wavefuel's two threads then shares its core, the case where a thread that is descheduled
holds the other at every synchronisation.

Usage: /usr/bin/python3 bench/time_blocking/run.py [--sizes 100000,1000000,10000000] [--repeats 3] [--load]
           [--bin bin/wavefuel] [--out bench/time_blocking/results.json]
"""
import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile

import h5py

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from busy_load import beside_load  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SCENARIO = os.path.join(ROOT, "bench", "scaling", "ring.yaml")
STEPS = {100_000: 800, 1_000_000: 160, 10_000_000: 48}  # multiples of 16: whole windows of the default before session 23
MODES = {"per-step": ["--set", "time.block_steps=1"], "windows": []}


def one_run(binary, n, threads, mode, tmp):
    out = os.path.join(tmp, "r.h5")
    steps = STEPS.get(n, max(16, int(1e8 / n) // 16 * 16))
    cmd = ["/usr/bin/time", "-f", "%M", binary, "run", SCENARIO, "-q", "-o", out, "--threads", str(threads),
           "--set", f"fleet.vehicles={n}", "--set", f"road.length_m={25 * n}",
           "--set", f"time.duration_s={steps / 10:g}"] + MODES[mode]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode:
        sys.exit(f"{' '.join(cmd)} failed: {p.stderr}")
    rss_kib = int(p.stderr.strip().splitlines()[-1])
    with h5py.File(out) as f:
        wall = float(f["meta/wall_time_s"][()])
        done = int(f["meta/steps_done"][()])
    os.unlink(out)
    return {"n": n, "threads": threads, "mode": mode, "steps": done, "wall_s": wall, "rate": n * done / wall,
            "rss_b_per_vehicle": rss_kib * 1024 / n, "load": os.getloadavg()[0]}


def table(runs, title):
    print(f"\n{title}\n")
    print("| N | threads | per-step | windows | windows / per-step | RSS per vehicle (per-step, windows) | load |")
    print("|---|---|---|---|---|---|---|")
    keys = sorted({(r["n"], r["threads"]) for r in runs})
    for n, th in keys:
        best = {}
        for mode in MODES:
            rs = [r for r in runs if r["n"] == n and r["threads"] == th and r["mode"] == mode]
            best[mode] = max(rs, key=lambda r: r["rate"])
        loads = [r["load"] for r in runs if r["n"] == n and r["threads"] == th]
        print(f"| {n:.0e} | {th} | {best['per-step']['rate']:.3g} | {best['windows']['rate']:.3g} | "
              f"{best['windows']['rate'] / best['per-step']['rate']:.2f} | "
              f"{best['per-step']['rss_b_per_vehicle']:.0f} B, {best['windows']['rss_b_per_vehicle']:.0f} B | "
              f"{min(loads):.1f}–{max(loads):.1f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="100000,1000000,10000000")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--load", action="store_true", help="also run beside two CPU-bound processes")
    ap.add_argument("--load-timeout", type=float, default=900)
    ap.add_argument("--bin", default=os.path.join(ROOT, "bin", "wavefuel"))
    ap.add_argument("--out", default=os.path.join(HERE, "results.json"))
    a = ap.parse_args()
    sizes = [int(s) for s in a.sizes.split(",")]
    # The copied binary finds no vehicle classes beside itself: name the checkout's (docs/energy.md).
    os.environ.setdefault("WAVEFUEL_VEHICLES", os.path.join(ROOT, "vehicles"))
    tmp = tempfile.mkdtemp(prefix="wf_tb_")
    binary = os.path.join(tmp, "wavefuel")
    shutil.copy(a.bin, binary)  # a rebuild during the runs cannot mix versions
    git = subprocess.run(["git", "-C", ROOT, "describe", "--always", "--dirty"], capture_output=True, text=True)
    res = {"machine": platform.processor() or platform.machine(), "git": git.stdout.strip(), "quiet": [], "loaded": []}
    try:
        for rep in range(a.repeats):
            for n in sizes:
                for th in (1, 2):
                    for mode in MODES:
                        res["quiet"].append(one_run(binary, n, th, mode, tmp))
        if a.load:
            loaded = [(n, th, mode) for _ in range(a.repeats) for n in sizes if n <= 1_000_000 for th in (1, 2)
                      for mode in MODES]
            res["loaded"] = beside_load(lambda: [one_run(binary, *c, tmp) for c in loaded], a.load_timeout)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    with open(a.out, "w") as f:
        json.dump(res, f, indent=1)
    print(f"wavefuel {res['git']}, best of {a.repeats}; vehicle-steps/s of the step loop")
    table(res["quiet"], "Quiet machine")
    if res["loaded"]:
        table(res["loaded"], "Beside two CPU-bound processes")


if __name__ == "__main__":
    main()
