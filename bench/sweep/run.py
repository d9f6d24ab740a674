#!/usr/bin/python3
"""Sweep throughput (bench/sweep/README.md): runs per hour of the 100-run sweep bench/sweep/sweep100.yaml (the
Sugiyama ring, 22 vehicles, 600 s) executed

  - as 100 separate `wavefuel run` processes, one after the other (the scripted alternative; each writes its file),
  - by `wavefuel sweep` on 1 and 2 threads (and on 2 threads with --per-run-files, which writes the same files),
  - by `mpirun -n 1|2 bin/wavefuel-mpi` (when `make mpi` has built it; --oversubscribe),

each the best of --repeats wall times (elapsed, process start to exit; repeats interleaved across configurations)
and the least CPU time (user + system of every process), plus the sum of the in-process run times the 1-thread
sweep recorded (/timing/wall_time: load + simulate, no process start). Prints the machine, one `BENCH sweep ...`
line per measurement and a Markdown table. Needs bin/wavefuel (make) and /usr/bin/python3 with h5py.

  bench/sweep/run.py [--repeats 3] [--out output/bench_sweep]
"""
import argparse
import os
import platform
import resource
import shlex
import shutil
import subprocess
import sys
import time

import h5py

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
BIN = os.path.join(ROOT, "bin", "wavefuel")
MPI_BIN = os.path.join(ROOT, "bin", "wavefuel-mpi")
SWEEP = os.path.join(HERE, "sweep100.yaml")


def timed(cmd, env=None):
    """Wall time and CPU time (user + system of the process and its children) of one command."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, cwd=ROOT)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def machine():
    cpu = "unknown"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    cc = subprocess.run(["gcc", "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    return f"{os.cpu_count()} cores, {cpu}, {platform.system()} {platform.release()}, {cc}"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=os.path.join(ROOT, "output", "bench_sweep"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    # The copied binary finds no vehicle classes beside itself: name the checkout's (docs/energy.md).
    os.environ.setdefault("WAVEFUEL_VEHICLES", os.path.join(ROOT, "vehicles"))
    # Private copies: a rebuild of bin/ during the measurement (make in another shell) must not break or skew it.
    global BIN, MPI_BIN
    for name in ("BIN", "MPI_BIN"):
        src = globals()[name]
        if os.path.exists(src):
            dst = os.path.join(a.out, os.path.basename(src))
            shutil.copy2(src, dst)
            globals()[name] = dst
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    print(f"machine: {machine()}")
    print(f"load average at start: {os.getloadavg()}")

    cmds = subprocess.run([BIN, "sweep", SWEEP, "--list"], check=True, capture_output=True, text=True,
                          cwd=ROOT).stdout.splitlines()
    n = len(cmds)
    assert n == 100, n
    table = os.path.join(a.out, "sweep100.h5")
    runs_dir = os.path.join(a.out, "runs")

    def singles():
        wall = cpu = 0.0
        for i, c in enumerate(cmds):
            w, u = timed([BIN] + shlex.split(c)[1:] + ["-o", os.path.join(a.out, f"single_{i}.h5"), "-q",
                                                      "--threads", "1", "--force"])
            wall, cpu = wall + w, cpu + u
        return wall, cpu

    def sweep(threads, per_run=False):
        def go():
            shutil.rmtree(runs_dir, ignore_errors=True)
            extra = ["--per-run-files", runs_dir] if per_run else []
            return timed([BIN, "sweep", SWEEP, "-o", table, "--force", "-q", "--threads", str(threads)] + extra)
        return go

    def mpi(ranks):
        return lambda: timed(["mpirun", "-n", str(ranks), "--oversubscribe", MPI_BIN, SWEEP, "-o", table, "--force",
                              "-q"], env=env)

    configs = [("100 x wavefuel run", singles, "separate processes, each writes its file"),
               ("sweep --threads 1", sweep(1), "table only"),
               ("sweep --threads 2", sweep(2), "table only"),
               ("sweep --threads 2 --per-run-files", sweep(2, True), "table + 100 run files")]
    if os.path.exists(MPI_BIN) and shutil.which("mpirun"):
        configs += [(f"mpirun -n {k} wavefuel-mpi", mpi(k), "includes mpirun start-up") for k in (1, 2)]
    else:
        print("note: bin/wavefuel-mpi or mpirun missing (make mpi): MPI rows skipped")
    walls = {c[0]: [] for c in configs}
    cpus = {c[0]: [] for c in configs}
    inproc = {}
    # Repeats interleaved, so that a change of the machine's load affects every configuration alike.
    for r in range(a.repeats):
        for name, fn, _ in configs:
            w, u = fn()
            walls[name].append(w)
            cpus[name].append(u)
            if name == "sweep --threads 1":
                inproc[r] = h5py.File(table, "r")["timing/wall_time"][()].sum()
            print(f"BENCH sweep config={name.replace(' ', '_')} runs={n} repeat={r} wall_s={w:.3f} cpu_s={u:.3f} "
                  f"runs_per_hour={3600 * n / w:.4g} load={os.getloadavg()[0]:.2f}", flush=True)
    results = [(name, min(walls[name]), min(cpus[name]), note) for name, _, note in configs]
    print(f"load average at end: {os.getloadavg()}")
    single_w, single_c = results[0][1], results[0][2]
    # The 1-thread sweep's own overhead, from one invocation: its wall time against the sum of its runs' times.
    r1 = min(range(a.repeats), key=lambda r: walls["sweep --threads 1"][r])
    sweep1, inproc1 = walls["sweep --threads 1"][r1], inproc[r1]
    print(f"\n| configuration | wall s (best of {a.repeats}) | runs/hour | CPU s (user+sys, least) | runs/CPU-hour | "
          "wall vs separate runs | CPU vs separate runs | note |")
    print("|---|---|---|---|---|---|---|---|")
    for name, w, c, note in results:
        print(f"| {name} | {w:.2f} | {3600 * n / w:,.0f} | {c:.2f} | {3600 * n / c:,.0f} | {w / single_w:.2f} | "
              f"{c / single_c:.2f} | {note} |")
    print(f"\nbest 1-thread sweep: wall {sweep1:.2f} s, sum of its runs' in-process times (/timing/wall_time) "
          f"{inproc1:.2f} s: process start, coordination and table writes = {100 * (sweep1 - inproc1) / sweep1:.1f} % "
          "of its wall time")


if __name__ == "__main__":
    sys.exit(main())
