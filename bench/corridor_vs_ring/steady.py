#!/usr/bin/env python3
"""Corridor vs ring in steady state, measured inside one process: the corridor of corridor.yaml is filled
(--fill-s), a ring of as many vehicles (ring.yaml, 25 m per vehicle) is built beside it, on each thread count,
and then every run is stepped --slice-steps steps in turn, --slices times, each slice timed alone
(time.perf_counter around Simulation.step). The runs write their result files as `wavefuel run` does (a record
every second into HDF5), into a temporary directory.

A slice of the corridor and one of the ring are taken a second apart, so the ratio of each pair meets the same load
of the machine; the table gives the best slice of each run and the median of the pairs' ratios. This replaces the
differences of whole runs of run.py for the corridor / ring criterion of issue 16: on a shared machine those
differences of two process times moved by tens of percent from one run to the next.

usage: steady.py [--lib NAME=PATH]... [--threads 1,2] [--length-m 150000] [--fill-s 5000] [--slice-steps 1000]
                 [--slices 12] [--rounds 1] [--set KEY=VALUE]... [--corridor-set KEY=VALUE]...
--set applies to both scenarios: `--set time.thread_check_steps=0` keeps each run on its thread count (the thread
governor may otherwise move a run to one thread for a while, after a probe that a busy moment favoured).
Each --lib (a libwavefuel.so; default: this tree's lib/libwavefuel.so) runs in a process of its own, one after the
other, --rounds times (A B A B ...). Needs `make python`; run with /usr/bin/python3."""
import argparse
import json
import os
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "../.."))
sys.path.insert(0, os.path.dirname(HERE))
import lib_child  # noqa: E402


def child(args):
    """One library: build, fill, then time the slices; JSON of the per-slice rates on stdout."""
    sys.path.insert(0, os.path.join(ROOT, "python"))
    import wavefuel as wf
    threads = [int(t) for t in args.threads.split(",")]
    dt = 0.1  # both scenarios' step (corridor.yaml, ring.yaml)
    sims = {}
    with tempfile.TemporaryDirectory() as tmp:
        for th in threads:
            sc = wf.Scenario.load(os.path.join(HERE, "corridor.yaml"),
                                  overrides={"road.length_m": args.length_m, "time.duration_s": 1e6,
                                             **dict(kv.split("=", 1) for kv in args.set + args.corridor_set)})
            s = wf.Simulation(sc, threads=th, output=os.path.join(tmp, f"corridor{th}.h5"))
            s.step(int(round(args.fill_s / dt)))
            sims[("corridor", th)] = s
        n = sims[("corridor", threads[0])].n_vehicles
        for th in threads:
            sc = wf.Scenario.load(os.path.join(HERE, "ring.yaml"),
                                  overrides={"fleet.vehicles": n, "road.length_m": 25.0 * n, "time.duration_s": 1e6,
                                             **dict(kv.split("=", 1) for kv in args.set)})
            s = wf.Simulation(sc, threads=th, output=os.path.join(tmp, f"ring{th}.h5"))
            s.step(args.slice_steps)  # caches and pages warm, as the corridor's after its fill
            sims[("ring", th)] = s
        rates = {f"{k[0]} {k[1]}": [] for k in sims}
        for _ in range(args.slices):
            for (road, th), s in sims.items():
                n0 = s.n_vehicles
                t0 = time.perf_counter()
                s.step(args.slice_steps)
                wall = time.perf_counter() - t0
                # a corridor's count changes by a few vehicles over a slice: its mean stands for every step's
                rates[f"{road} {th}"].append(args.slice_steps * 0.5 * (n0 + s.n_vehicles) / wall)
        for s in sims.values():
            s.close()
    json.dump({"vehicles": n, "rates": rates}, sys.stdout)


def median(v):
    v = sorted(v)
    return v[len(v) // 2] if len(v) % 2 else 0.5 * (v[len(v) // 2 - 1] + v[len(v) // 2])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--lib", action="append", default=[], help="NAME=PATH of a libwavefuel.so (repeatable)")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--length-m", type=float, default=150000.0)
    ap.add_argument("--fill-s", type=float, default=5000.0)
    ap.add_argument("--slice-steps", type=int, default=1000)
    ap.add_argument("--slices", type=int, default=12)
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--corridor-set", action="append", default=[], metavar="KEY=VALUE",
                    help="a key of the corridor's scenario (repeatable), e.g. time.block_steps=16")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a key of both scenarios (repeatable), e.g. time.thread_check_steps=0")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args)
        return
    libs = lib_child.libs(args.lib)
    got = {name: {} for name, _ in libs}
    n = {}
    for _ in range(args.rounds):
        for name, path in libs:
            r = lib_child.run_child(__file__, path)
            n[name] = r["vehicles"]
            for k, v in r["rates"].items():
                got[name].setdefault(k, []).extend(v)
    print("| library | threads | vehicles | corridor M veh-steps/s (best, median) | ring M veh-steps/s (best, median) |"
          " best / best | median of the pairs' ratios |")
    print("|---|---|---|---|---|---|---|")
    for name, _ in libs:
        for th in args.threads.split(","):
            c, r = got[name][f"corridor {th}"], got[name][f"ring {th}"]
            pairs = [a / b for a, b in zip(c, r)]
            print("| %s | %s | %d | %.1f, %.1f | %.1f, %.1f | %.2f | %.2f |" % (
                name, th, n[name], max(c) / 1e6, median(c) / 1e6, max(r) / 1e6, median(r) / 1e6, max(c) / max(r),
                median(pairs)))


if __name__ == "__main__":
    main()
