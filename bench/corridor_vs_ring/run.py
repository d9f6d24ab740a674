#!/usr/bin/env python3
"""Corridor vs ring: vehicle-steps per second of a corridor holding about N vehicles and of a ring of N vehicles,
with the same drivers, classes and step, for each binary and thread count.

Both rates are differential, so that start-up, loading and writing cancel: the corridor starts empty and runs
fill_s and fill_s + window_s (identical up to fill_s: runs are deterministic); its rate is the difference of their
vehicle-steps (from the `vehicles` record every second) over the difference of their times. The ring (N = the
corridor's mean count in the window) runs window_s and 2 window_s. Times are the step loop's wall time
(/meta/wall_time_s) or, with --cpu, the process's CPU time (user + system: steadier on a shared machine, meaningful
for one thread only); each is the least of --repeats runs (the least disturbed).

usage: run.py [--bin NAME=PATH]... [--threads 1,2] [--length-m 150000] [--fill-s 5000] [--window-s 1000]
              [--repeats 3] [--cpu]"""
import argparse
import os
import resource
import subprocess
import sys
import tempfile

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def run(binary, scenario, sets, args, threads, out):
    """(record times, vehicles per record, dt, least time of the repeats)."""
    cmd = [binary, "run", os.path.join(HERE, scenario), "-o", out, "--force", "-q", "--threads", str(threads)]
    for s in sets:
        cmd += ["--set", s]
    best = float("inf")
    for _ in range(args.repeats):
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        subprocess.run(cmd, check=True)
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        with h5py.File(out, "r") as f:
            t = f["timeseries/t"][()]
            n = f["timeseries/vehicles"][()] if "vehicles" in f["timeseries"] else None
            dt = float(f["meta/dt"][()])
            wall = float(f["meta/wall_time_s"][()])
        cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
        best = min(best, cpu if args.cpu else wall)
    return t, n, dt, best


def corridor_rate(binary, threads, args, tmp):
    """(vehicle-steps per second, mean vehicles) over the window after the fill."""
    common = ["road.length_m=%g" % args.length_m]
    _, _, dt, w1 = run(binary, "corridor.yaml", common + ["time.duration_s=%g" % args.fill_s], args, threads,
                       os.path.join(tmp, "c1.h5"))
    t2, n2, _, w2 = run(binary, "corridor.yaml", common + ["time.duration_s=%g" % (args.fill_s + args.window_s)],
                        args, threads, os.path.join(tmp, "c2.h5"))
    # Steps [fill, fill + window): the record at t counts the vehicles stepped over the next second.
    win = (t2 >= args.fill_s - 1e-9) & (t2 < args.fill_s + args.window_s - 1e-9)
    veh_steps = float(np.sum(n2[win])) * round((t2[1] - t2[0]) / dt)
    return veh_steps / (w2 - w1), float(np.mean(n2[win]))


def ring_rate(binary, threads, n, args, tmp):
    sets = ["fleet.vehicles=%d" % n, "road.length_m=%g" % (25.0 * n)]
    _, _, dt, w1 = run(binary, "ring.yaml", sets + ["time.duration_s=%g" % args.window_s], args, threads,
                       os.path.join(tmp, "r1.h5"))
    _, _, _, w2 = run(binary, "ring.yaml", sets + ["time.duration_s=%g" % (2 * args.window_s)], args, threads,
                      os.path.join(tmp, "r2.h5"))
    return n * round(args.window_s / dt) / (w2 - w1)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", action="append", default=[], help="NAME=PATH of a wavefuel binary (repeatable)")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--length-m", type=float, default=150000.0)
    ap.add_argument("--fill-s", type=float, default=5000.0)
    ap.add_argument("--window-s", type=float, default=1000.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cpu", action="store_true", help="CPU time instead of wall time (one thread)")
    args = ap.parse_args()
    bins = [b.split("=", 1) for b in args.bin] or [["this", os.path.join(HERE, "../../bin/wavefuel")]]
    print("| binary | threads | time | corridor vehicles | corridor M veh-steps/s | ring M veh-steps/s | corridor / ring |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, path in bins:
            for th in [int(x) for x in args.threads.split(",")]:
                rc, nc = corridor_rate(path, th, args, tmp)
                rr = ring_rate(path, th, int(round(nc)), args, tmp)
                print("| %s | %d | %s | %.0f | %.1f | %.1f | %.2f |" % (name, th, "cpu" if args.cpu else "wall", nc,
                                                                     rc / 1e6, rr / 1e6, rc / rr))
                sys.stdout.flush()


if __name__ == "__main__":
    main()
