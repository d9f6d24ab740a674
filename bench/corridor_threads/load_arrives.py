#!/usr/bin/python3
"""A load that arrives in the middle of a run (the thread governor's alarm, src/core/governor.h).

The corridor of bench/corridor_vs_ring (about 5000 vehicles on 150 km once full) is filled (--fill-s) on the quiet
machine, in one process through the Python package, once on one thread and once on two threads with the governor
(time.thread_check_steps 1024, the default): on an idle machine two threads win every probe, so by then the governor
probes only every 32 768 steps or more. Then two CPU-bound processes start beside it (bench/busy_load.py) and the two
runs step --slices slices of --slice-steps steps in turn, each slice timed alone. The table gives, for each library,
the loaded slices' vehicle-steps per second of wall time on one thread and on two, slice by slice, and the whole
loaded stretch's (total vehicle-steps over total time).

usage: load_arrives.py [--lib NAME=PATH]... [--fill-s 5000] [--slice-steps 1000] [--slices 10]
Each --lib (a libwavefuel.so; default: this tree's lib/libwavefuel.so) runs in a process of its own, one after the
other. Needs `make python`; run with /usr/bin/python3."""
import argparse
import json
import os
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SCENARIO = os.path.join(ROOT, "bench", "corridor_vs_ring", "corridor.yaml")
sys.path.insert(0, os.path.dirname(HERE))
from busy_load import start_load  # noqa: E402
import lib_child  # noqa: E402


def child(args):
    sys.path.insert(0, os.path.join(ROOT, "python"))
    import wavefuel as wf
    sims = {}
    rates = {1: [], 2: []}
    with tempfile.TemporaryDirectory() as tmp:
        for th in (1, 2):
            sc = wf.Scenario.load(SCENARIO, overrides={"road.length_m": 150000, "time.duration_s": 1e6})
            s = wf.Simulation(sc, threads=th, output=os.path.join(tmp, "t%d.h5" % th))
            s.step(int(round(args.fill_s / 0.1)))
            sims[th] = s
        load = start_load(600)
        try:
            time.sleep(0.5)  # the busy loops running
            for _ in range(args.slices):
                for th, s in sims.items():
                    n0 = s.n_vehicles
                    t0 = time.perf_counter()
                    s.step(args.slice_steps)
                    wall = time.perf_counter() - t0
                    rates[th].append((args.slice_steps * 0.5 * (n0 + s.n_vehicles), wall))
        finally:
            for p in load:
                p.kill()
                p.wait()
        for s in sims.values():
            s.close()
    json.dump(rates, sys.stdout)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--lib", action="append", default=[], help="NAME=PATH of a libwavefuel.so (repeatable)")
    ap.add_argument("--fill-s", type=float, default=5000.0)
    ap.add_argument("--slice-steps", type=int, default=1000)
    ap.add_argument("--slices", type=int, default=10)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args)
        return
    print("| library | threads | loaded slices, M veh-steps/s each | whole loaded stretch, M veh-steps/s |")
    print("|---|---|---|---|")
    for name, path in lib_child.libs(args.lib):
        for th, sl in sorted(lib_child.run_child(__file__, path).items()):
            each = " ".join("%.1f" % (w / t / 1e6) for w, t in sl)
            total = sum(w for w, _ in sl) / sum(t for _, t in sl)
            print("| %s | %s | %s | %.1f |" % (name, th, each, total / 1e6))


if __name__ == "__main__":
    main()
