#!/usr/bin/python3
"""Lanes (issue 18): the cost of lanes and lane changes on a ring of N vehicles (bench/lanes/ring.yaml: IDM with
noise, two classes, a record every second, 30 m of road per vehicle and lane), side by side in one run:

  one lane        the ring on one lane (the single-lane engine, time-blocked windows included)
  3 lanes, none   three lanes, lane_change none (each lane a ring of its own; no decisions)
  3 lanes, MOBIL  three lanes with MOBIL at every step, lanes equal at the start (few changes: decisions cost)
  3 lanes, moving three lanes with MOBIL starting 50 / 30 / 20 % (thousands of changes: decisions and moves)

Each repeat runs the cases in turn (so they meet the same load); the table gives the best of --repeats as
vehicle-steps per second of the step loop (N x /meta/steps_done / /meta/wall_time_s), the ratio to one lane, the
lane changes of the run and the peak RSS per vehicle (GNU time %M).

Usage: /usr/bin/python3 bench/lanes/run.py [--n 100000] [--steps 200] [--threads 1] [--repeats 3]
           [--bin bin/wavefuel] [--out bench/lanes/results.json]
"""
import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile

import h5py

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SCENARIO = os.path.join(HERE, "ring.yaml")


def cases(n):
    counts = [n // 2, (3 * n) // 10, n - n // 2 - (3 * n) // 10]
    return {
        "one lane": ["--set", "road.lanes=1"],
        "3 lanes, none": ["--set", "fleet.drivers[0].lane_change.model=none"],
        "3 lanes, MOBIL": [],
        "3 lanes, moving": ["--lane-counts", ", ".join(map(str, counts))],
    }


def one_run(binary, n, steps, threads, args, tmp):
    out = os.path.join(tmp, "r.h5")
    scen = SCENARIO
    if args and args[0] == "--lane-counts":
        scen = os.path.join(tmp, "ring.yaml")
        text = open(SCENARIO).read().replace("  placement: random", f"  placement: random\n  lane_counts: [{args[1]}]")
        open(scen, "w").write(text)
        args = []
    cmd = ["/usr/bin/time", "-f", "%M", binary, "run", scen, "-q", "-o", out, "--threads", str(threads), "--set",
           f"fleet.vehicles={n}", "--set", f"road.length_m={10 * n}", "--set", f"time.duration_s={steps / 10:g}"] + args
    p = subprocess.run(cmd, capture_output=True, text=True, env=dict(os.environ, WAVEFUEL_VEHICLES=os.path.join(ROOT, "vehicles")))
    if p.returncode:
        sys.exit(f"{' '.join(cmd)} failed: {p.stderr}")
    rss_kib = int(p.stderr.strip().splitlines()[-1])
    with h5py.File(out) as f:
        wall = float(f["meta/wall_time_s"][()])
        done = int(f["meta/steps_done"][()])
        changes = int(f["summary/lane_changes"][()]) if "summary/lane_changes" in f else 0
    os.unlink(out)
    return {"wall_s": wall, "rate": n * done / wall, "changes": changes, "rss_b_per_vehicle": rss_kib * 1024 / n,
            "load": os.getloadavg()[0]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100000)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--bin", default=os.path.join(ROOT, "bin", "wavefuel"))
    ap.add_argument("--out", default=os.path.join(HERE, "results.json"))
    a = ap.parse_args()
    cs = cases(a.n)
    best = {}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(a.repeats):
            for name, args in cs.items():
                r = one_run(a.bin, a.n, a.steps, a.threads, args, tmp)
                if name not in best or r["rate"] > best[name]["rate"]:
                    best[name] = r
    base = best["one lane"]["rate"]
    print(f"N = {a.n}, {a.steps} steps, {a.threads} thread(s), best of {a.repeats} ({platform.node()})\n")
    print("| case | vehicle-steps/s | / one lane | lane changes | peak RSS per vehicle | load |")
    print("|---|---|---|---|---|---|")
    for name, r in best.items():
        print(f"| {name} | {r['rate']:.3g} | {r['rate'] / base:.2f} | {r['changes']} | "
              f"{r['rss_b_per_vehicle']:.0f} B | {r['load']:.1f} |")
    json.dump({"n": a.n, "steps": a.steps, "threads": a.threads, "repeats": a.repeats, "best": best},
              open(a.out, "w"), indent=1)
    print(f"\nwrote {a.out}")


if __name__ == "__main__":
    main()
