#!/usr/bin/env python3
"""Corridor vs ring: vehicle-steps per second of wall time of a corridor holding about N vehicles and of a ring of
N vehicles, with the same drivers, classes and step, for each binary and thread count.

The corridor starts empty; its rate is measured over a window after it has filled: two runs of durations
fill_s and fill_s + window_s (identical up to fill_s: the runs are deterministic), and the rate is the difference of
their vehicle-steps (from the `vehicles` record every second) over the difference of their step-loop wall times
(/meta/wall_time_s). The ring runs window_s with N = the corridor's mean count in the window. Every wall time is the
least of --repeats runs (the machine may be shared: the least is the one least disturbed).

usage: run.py [--bin NAME=PATH]... [--threads 1,2] [--length-m 150000] [--fill-s 5000] [--window-s 1000]
              [--repeats 3]"""
import argparse
import os
import subprocess
import sys
import tempfile

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


REPEATS = [3]


def run(binary, scenario, sets, threads, out):
    cmd = [binary, "run", os.path.join(HERE, scenario), "-o", out, "--force", "-q", "--threads", str(threads)]
    for s in sets:
        cmd += ["--set", s]
    wall = float("inf")
    for _ in range(REPEATS[0]):
        subprocess.run(cmd, check=True)
        with h5py.File(out, "r") as f:
            t = f["timeseries/t"][()]
            n = f["timeseries/vehicles"][()] if "vehicles" in f["timeseries"] else None
            dt = float(f["meta/dt"][()])
            wall = min(wall, float(f["meta/wall_time_s"][()]))
    return t, n, dt, wall


def corridor_rate(binary, threads, args, tmp):
    """(vehicle-steps per second, mean vehicles) over the window after the fill."""
    common = ["road.length_m=%g" % args.length_m]
    t1, n1, dt, w1 = run(binary, "corridor.yaml", common + ["time.duration_s=%g" % args.fill_s], threads,
                         os.path.join(tmp, "c1.h5"))
    t2, n2, _, w2 = run(binary, "corridor.yaml", common + ["time.duration_s=%g" % (args.fill_s + args.window_s)],
                        threads, os.path.join(tmp, "c2.h5"))
    # Steps [fill, fill + window): the record at t counts the vehicles stepped over the next second.
    win = (t2 >= args.fill_s - 1e-9) & (t2 < args.fill_s + args.window_s - 1e-9)
    steps_per_rec = round((t2[1] - t2[0]) / dt)
    veh_steps = float(np.sum(n2[win])) * steps_per_rec
    return veh_steps / (w2 - w1), float(np.mean(n2[win]))


def ring_rate(binary, threads, n, args, tmp):
    sets = ["fleet.vehicles=%d" % n, "road.length_m=%g" % (25.0 * n), "time.duration_s=%g" % args.window_s]
    t, _, dt, w = run(binary, "ring.yaml", sets, threads, os.path.join(tmp, "r.h5"))
    steps = round(args.window_s / dt)
    return n * steps / w


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", action="append", default=[], help="NAME=PATH of a wavefuel binary (repeatable)")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--length-m", type=float, default=150000.0)
    ap.add_argument("--fill-s", type=float, default=5000.0)
    ap.add_argument("--window-s", type=float, default=1000.0)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    REPEATS[0] = args.repeats
    bins = [b.split("=", 1) for b in args.bin] or [["this", os.path.join(HERE, "../../bin/wavefuel")]]
    print("| binary | threads | corridor vehicles | corridor M veh-steps/s | ring M veh-steps/s | corridor / ring |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, path in bins:
            for th in [int(x) for x in args.threads.split(",")]:
                rc, nc = corridor_rate(path, th, args, tmp)
                rr = ring_rate(path, th, int(round(nc)), args, tmp)
                print("| %s | %d | %.0f | %.1f | %.1f | %.2f |" % (name, th, nc, rc / 1e6, rr / 1e6, rc / rr))
                sys.stdout.flush()


if __name__ == "__main__":
    main()
