#!/usr/bin/python3
"""Ring threads on a quiet and on a loaded machine (issue 20: two threads never slower than one).

The ring of bench/scaling/ring.yaml (IDM with noise, two energy classes, ballistic dt 0.1 s, a record every second,
25 m of road per vehicle) for about --work vehicle-steps (1e8: 1.5 s on two busy cores), in three cases that
alternate within each repeat:

- `one`: one thread;
- `two-before`: two threads as before session 23, windows of 16 steps and no thread governor
  (time.block_steps=16, time.thread_check_steps=0);
- `two`: two threads with the defaults (windows of 64 steps, the governor: time.thread_check_steps=1024);
- `one-again`: one thread again, last: its ratio to `one` is what two runs of the same case differ by within a repeat
  (the noise that a ratio of two threads to one carries too).

first on the machine as it is, then (--load) beside two CPU-bound processes (bench/busy_load.py: busy loops that
stop themselves after --load-timeout seconds, and are killed at the end). Rates are vehicle-steps per second of the
step loop (N x /meta/steps_done / /meta/wall_time_s). The table gives each case's best and median, and the range over
the repeats of each repeat's own ratio of two threads to one (its runs seconds apart, under the same load).

usage: run.py [--bin bin/wavefuel] [--sizes 10000,100000,1000000] [--work 1e8] [--repeats 6] [--load]
              [--load-timeout 900] [--json FILE]
"""
import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile

import h5py

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SCENARIO = os.path.join(ROOT, "bench", "scaling", "ring.yaml")
sys.path.insert(0, os.path.dirname(HERE))
from busy_load import beside_load  # noqa: E402

CASES = {"one": (1, []), "two-before": (2, ["time.block_steps=16", "time.thread_check_steps=0"]), "two": (2, []),
         "one-again": (1, [])}


def one_run(binary, n, case, work, tmp):
    threads, sets = CASES[case]
    out = os.path.join(tmp, "r.h5")
    steps = max(160, int(work / n) // 16 * 16)
    cmd = [binary, "run", SCENARIO, "-q", "-o", out, "--force", "--threads", str(threads), "--set",
           f"fleet.vehicles={n}", "--set", f"road.length_m={25 * n}", "--set", f"time.duration_s={steps / 10:g}"]
    for s in sets:
        cmd += ["--set", s]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode:
        sys.exit(f"{' '.join(cmd)} failed: {p.stderr}")
    with h5py.File(out) as f:
        wall = float(f["meta/wall_time_s"][()])
        done = int(f["meta/steps_done"][()])
    return {"n": n, "case": case, "rate": n * done / wall, "load": os.getloadavg()[0]}


def series(binary, sizes, work, repeats, tmp):
    runs = []
    for rep in range(repeats):
        for n in sizes:
            for case in CASES:
                runs.append(dict(one_run(binary, n, case, work, tmp), rep=rep))
    return runs


def table(runs, title):
    print(f"\n{title}\n")
    print("| N | one thread best (median) | two-before best (median) | two best (median) | one-again best (median) | "
          "two-before / one, each repeat | two / one, each repeat | one-again / one, each repeat | load |")
    print("|---|---|---|---|---|---|---|---|---|")
    for n in sorted({r["n"] for r in runs}):
        rs = [r for r in runs if r["n"] == n]
        cells, ratio = [], {}
        for case in CASES:
            rates = [r["rate"] for r in rs if r["case"] == case]
            cells.append(f"{max(rates):.3g} ({statistics.median(rates):.3g})")
        for case in ("two-before", "two", "one-again"):
            rate = {(r["rep"], r["case"]): r["rate"] for r in rs}
            q = [rate[k, case] / rate[k, "one"] for k in sorted({r["rep"] for r in rs})]
            ratio[case] = f"{min(q):.2f}–{max(q):.2f} (median {statistics.median(q):.2f})"
        loads = [r["load"] for r in rs]
        print(f"| {n:.0e} | {' | '.join(cells)} | {ratio['two-before']} | {ratio['two']} | {ratio['one-again']} | "
              f"{min(loads):.1f}–{max(loads):.1f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.path.join(ROOT, "bin", "wavefuel"))
    ap.add_argument("--sizes", default="10000,100000,1000000")
    ap.add_argument("--work", type=float, default=1e8, help="vehicle-steps per run")
    ap.add_argument("--repeats", type=int, default=6)
    ap.add_argument("--load", action="store_true", help="also run beside two CPU-bound processes")
    ap.add_argument("--load-timeout", type=float, default=900)
    ap.add_argument("--json")
    a = ap.parse_args()
    sizes = [int(s) for s in a.sizes.split(",")]
    # The copied binary finds no vehicle classes beside itself: name the checkout's (docs/energy.md).
    os.environ.setdefault("WAVEFUEL_VEHICLES", os.path.join(ROOT, "vehicles"))
    tmp = tempfile.mkdtemp(prefix="wf_rt_")
    binary = os.path.join(tmp, "wavefuel")
    shutil.copy(a.bin, binary)  # a rebuild during the runs cannot mix versions
    ver = subprocess.run([binary, "--version"], capture_output=True, text=True).stdout.split("\n")[0]
    res = {"machine": platform.processor() or platform.machine(), "version": ver, "quiet": [], "loaded": []}
    try:
        res["quiet"] = series(binary, sizes, a.work, a.repeats, tmp)
        if a.load:
            res["loaded"] = beside_load(lambda: series(binary, sizes, a.work, a.repeats, tmp), a.load_timeout)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1)
    print(f"{res['version']}; vehicle-steps/s of the step loop, {a.repeats} repeats of {a.work:.3g} vehicle-steps")
    table(res["quiet"], "Quiet machine")
    if res["loaded"]:
        table(res["loaded"], "Beside two CPU-bound processes")


if __name__ == "__main__":
    main()
