#!/usr/bin/env python3
"""Corridor vs ring: vehicle-steps per second of a corridor holding about N vehicles and of a ring of N vehicles,
with the same drivers, classes and step, for each binary and thread count.

Both rates are differential, so that start-up, loading and writing cancel: the corridor starts empty and runs
fill_s and fill_s + window_s (identical up to fill_s: runs are deterministic); its rate is the difference of their
vehicle-steps (from the `vehicles` record every second) over the difference of their times. The ring (N = the
corridor's mean count in the window) runs window_s and 2 window_s. Times are the step loop's wall time
(/meta/wall_time_s) or, with --cpu, the process's CPU time (user + system: steadier on a shared machine, meaningful
for one thread only); each is the least of --repeats runs (the least disturbed). Each repeat runs every binary and
thread count in turn, so that all meet the machine's load alike. The last column is the median over the repeats of
each repeat's own ratio (its corridor and ring runs seconds apart): steadier than the ratio of best times
when the machine's speed drifts between minutes.

usage: run.py [--bin NAME=PATH]... [--threads 1,2] [--length-m 150000] [--fill-s 5000] [--window-s 1000]
              [--repeats 3] [--cpu]"""
import argparse
import os
import resource
import subprocess
import tempfile

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def run(binary, scenario, sets, args, threads, out):
    """(record times, vehicles per record, dt, time) of one run."""
    cmd = [binary, "run", os.path.join(HERE, scenario), "-o", out, "--force", "-q", "--threads", str(threads)]
    for s in sets:
        cmd += ["--set", s]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(cmd, check=True)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    with h5py.File(out, "r") as f:
        t = f["timeseries/t"][()]
        n = f["timeseries/vehicles"][()] if "vehicles" in f["timeseries"] else None
        dt = float(f["meta/dt"][()])
        wall = float(f["meta/wall_time_s"][()])
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return t, n, dt, cpu if args.cpu else wall


class Case:
    """One binary on one thread count: the least time of each of its four runs over the repeats."""

    def __init__(self, name, path, threads):
        self.name, self.path, self.threads = name, path, threads
        self.best = {}
        self.ratios = []  # corridor / ring of each repeat (its four runs close in time)
        self.n = None  # the corridor's mean vehicles in the window, and the ring's size
        self.veh_steps = None

    def once(self, args, tmp):
        now = {}

        def keep(key, w):
            self.best[key] = min(self.best.get(key, w), w)
            now[key] = w
        road = ["road.length_m=%g" % args.length_m]
        _, _, dt, w = run(self.path, "corridor.yaml", road + ["time.duration_s=%g" % args.fill_s], args,
                          self.threads, os.path.join(tmp, "c1.h5"))
        keep("c1", w)
        t2, n2, _, w = run(self.path, "corridor.yaml", road + ["time.duration_s=%g" % (args.fill_s + args.window_s)],
                           args, self.threads, os.path.join(tmp, "c2.h5"))
        keep("c2", w)
        if self.n is None:
            # Steps [fill, fill + window): the record at t counts the vehicles stepped over the next second.
            win = (t2 >= args.fill_s - 1e-9) & (t2 < args.fill_s + args.window_s - 1e-9)
            self.veh_steps = float(np.sum(n2[win])) * round((t2[1] - t2[0]) / dt)
            self.n, self.dt = float(np.mean(n2[win])), dt
        n = int(round(self.n))
        ring = ["fleet.vehicles=%d" % n, "road.length_m=%g" % (25.0 * n)]
        for key, dur in (("r1", args.window_s), ("r2", 2 * args.window_s)):
            keep(key, run(self.path, "ring.yaml", ring + ["time.duration_s=%g" % dur], args, self.threads,
                          os.path.join(tmp, key + ".h5"))[3])
        rc, rr = self.rates(args, now)
        self.ratios.append(rc / rr)

    def rates(self, args, times=None):
        """(corridor, ring) vehicle-steps per second from the best times (or the given ones)."""
        w = times or self.best
        ring_steps = int(round(self.n)) * round(args.window_s / self.dt)
        return self.veh_steps / (w["c2"] - w["c1"]), ring_steps / (w["r2"] - w["r1"])


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
    print("| binary | threads | time | corridor vehicles | corridor M veh-steps/s | ring M veh-steps/s | corridor / ring |"
          " median of the repeats' ratios |")
    print("|---|---|---|---|---|---|---|---|")
    cases = [Case(name, path, int(th)) for name, path in bins for th in args.threads.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        # Every case runs once per repeat, in turn, so that all of them meet the machine's load alike.
        for _ in range(args.repeats):
            for c in cases:
                c.once(args, tmp)
    for c in cases:
        rc, rr = c.rates(args)
        print("| %s | %d | %s | %.0f | %.1f | %.1f | %.2f | %.2f |" % (
            c.name, c.threads, "cpu" if args.cpu else "wall", c.n, rc / 1e6, rr / 1e6, rc / rr,
            float(np.median(c.ratios))))

if __name__ == "__main__":
    main()
