#!/usr/bin/python3
"""Corridor threads on a quiet and on a loaded machine (time.thread_check_steps, docs/corridors.md).

The corridor of bench/corridor_vs_ring (IDM, noise, two classes, Edie fields, fed above capacity; about 5000
vehicles on 150 km once full) is run for --duration-s simulated seconds on one thread, on two threads always
(time.thread_check_steps=0) and on two threads with the governor (the default, 1024), each one step at a time and in
time-blocked windows of 9 steps (time.block_steps=9: the 9 steps between records), first on the machine as it is,
then beside two CPU-bound processes (busy loops that stop themselves after --load-timeout seconds and are killed at
the end). Cases alternate within each repeat; the table gives each case's best wall time of --repeats (whole
processes). Results are the same bits in every case (checked on the runs of the machine as it is: every dataset
outside /meta, with h5py).

usage: run.py [--bin bin/wavefuel] [--duration-s 6000] [--repeats 2] [--load-timeout 600] [--json FILE]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time


HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SCENARIO = os.path.join(ROOT, "bench", "corridor_vs_ring", "corridor.yaml")
sys.path.insert(0, os.path.join(ROOT, "tests"))
from h5same import compare  # noqa: E402 (the one comparison of two results)
sys.path.insert(0, os.path.dirname(HERE))
from busy_load import beside_load  # noqa: E402
# (name, threads, time.thread_check_steps, time.block_steps)
CASES = [("1 thread", 1, 1024, 1), ("2 threads, always", 2, 0, 1), ("2 threads, governor", 2, 1024, 1),
         ("1 thread, windows", 1, 1024, 9), ("2 threads, always, windows", 2, 0, 9),
         ("2 threads, governor, windows", 2, 1024, 9)]


def one_run(binary, args, threads, check, block, out):
    cmd = [binary, "run", SCENARIO, "-q", "--force", "-o", out, "--threads", str(threads),
           "--set", "road.length_m=150000", "--set", "time.duration_s=%g" % args.duration_s,
           "--set", "time.thread_check_steps=%d" % check, "--set", "time.block_steps=%d" % block]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True)
    return time.perf_counter() - t0


def measure(binary, args, tmp, label):
    best = {}
    for _ in range(args.repeats):
        for name, threads, check, block in CASES:
            out = os.path.join(tmp, "%s_%d_%d_%d.h5" % (label, threads, check, block))
            w = one_run(binary, args, threads, check, block, out)
            best[name] = min(best.get(name, w), w)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.path.join(ROOT, "bin", "wavefuel"))
    ap.add_argument("--duration-s", type=float, default=6000.0)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--load-timeout", type=float, default=600.0)
    ap.add_argument("--json")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        quiet = measure(args.bin, args, tmp, "quiet")
        ref = os.path.join(tmp, "quiet_1_1024_1.h5")
        for _, threads, check, block in CASES[1:]:
            _, bad = compare(ref, os.path.join(tmp, "quiet_%d_%d_%d.h5" % (threads, check, block)))
            if bad:
                sys.exit("run.py: results differ between thread or window settings: " + ", ".join(bad[:5]))
        loaded = beside_load(lambda: measure(args.bin, args, tmp, "load"), args.load_timeout)
        with open("/proc/loadavg") as f:
            loadavg = f.read().split()[0]
    print("| case | wall s, machine as it is | wall s, beside 2 busy processes |")
    print("|---|---|---|")
    for name, _, _, _ in CASES:
        print("| %s | %.2f | %.2f |" % (name, quiet[name], loaded[name]))
    print("(same bits in every case; load average at the end %s)" % loadavg)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"duration_s": args.duration_s, "quiet": quiet, "loaded": loaded}, f, indent=1)


if __name__ == "__main__":
    main()
