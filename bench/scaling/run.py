#!/usr/bin/python3
"""Scaling benchmark (issue 8): wavefuel's step loop on the ring of bench/scaling/ring.yaml (IDM, noise, two energy
classes, ballistic dt 0.1 s, output every 1 s, 25 m of road per vehicle) for N = 22 ... 1e7 vehicles.

Measures, each configuration best of --repeats runs (the machine may be shared: the 1-minute load average before
and after each configuration is recorded next to its figures):
  throughput   vehicle-steps per second = N x /meta/steps_done / /meta/wall_time_s (the step loop, energy,
               statistics and output included), and the same over the whole process wall (setup, HDF5 included);
  strong       fixed N on 1 and 2 threads: speedup T1/T2 and parallel efficiency speedup/2;
  weak         fixed N per thread (1e5 and 1e6): N on 1 thread against 2N on 2 threads;
  memory       peak RSS of the child (GNU time %M) / N, also minus the N = 22 baseline; with the default
               trajectories off and, at 1e6 and 1e7, with trajectories on (one run each);
  phases       /meta/phase_time per /meta/phase_name of the best run;
  bandwidth    build/bench/stream_triad (STREAM triad, 1 and 2 threads) for the roofline columns.

The binary is copied once at the start, so a rebuild during the sweep cannot mix two versions; its git hash
(/meta/git_hash) and SHA-256 are recorded. Results: bench/scaling/results.json (every run) and results.csv (one
row per configuration); the Markdown tables are printed at the end and by --table from results.json.

Usage: /usr/bin/python3 bench/scaling/run.py [--repeats 3] [--repeats-large R] [--sizes 22,1000,...]
           [--bin bin/wavefuel] [--out bench/scaling] [--no-triad] [--no-weak] [--no-memory] [--table [results.json]]
The roofline columns use BYTES_PER_VSTEP below, counted in bench/README.md ("STREAM triad and roofline") from
src/core/engine.c; recount it when the step loop changes.
"""
import argparse
import csv
import datetime
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import h5py

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, "bench"))
from machine import machine  # noqa: E402 (what a benchmark ran on)
SCENARIO = os.path.join(HERE, "ring.yaml")
SPACING_M = 25.0  # road per vehicle, as in ring.yaml
DT_S = 0.1
SIZES = [22, 1000, 10_000, 100_000, 1_000_000, 10_000_000]
# Steps per size: about 1e8 vehicle-steps at 1e5 and 1e6 (about 1 s at the 1e8 vehicle-steps/s target), fewer
# at 1e7 where setup dominates the process wall; many at small N where a step takes microseconds.
STEPS = {22: 100_000, 1000: 20_000, 10_000: 5_000, 100_000: 1_000, 1_000_000: 200, 10_000_000: 50}
WEAK_PER_THREAD = [100_000, 1_000_000]
TRAJ_SIZES = [1_000_000, 10_000_000]
# DRAM traffic of one vehicle-step of the step loop at large N, as counted in bench/README.md from src/core/engine.c:
# loads + stores of the fleet arrays the fused step touches (every step, records included; no array is only
# written, so no write-allocate reads). It divides the triad bandwidth counted the same way (32 B per element).
BYTES_PER_VSTEP = 148
IN_CACHE_N = 1000  # its working set (~100 B per vehicle) fits the 1 MiB L2: the rate there is the compute roof


def steps_for(n):
    if n in STEPS:
        return STEPS[n]
    # Sizes not in the table (weak scaling 2N): the step count of the nearest size below.
    return STEPS[max(s for s in STEPS if s <= n)] if n >= min(STEPS) else STEPS[min(STEPS)]


def loadavg():
    return os.getloadavg()[0]


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for blk in iter(lambda: f.read(1 << 20), b""):
            h.update(blk)
    return h.hexdigest()


def timed_child(cmd, tmp, env):
    """Run cmd to completion; returns (wall s, CPU s, peak RSS KiB). Raises on a non-zero exit.

    The peak RSS comes from GNU time's %M (its child's ru_maxrss): ru_maxrss of a child forked by this Python
    process would start at Python's own resident size (the high-water mark survives exec), hiding anything below
    ~50 MB. Without /usr/bin/time the child's own ru_maxrss is used and the figure is a bound from above."""
    gnu_time = shutil.which("time", path="/usr/bin")
    rss_file = os.path.join(tmp, "maxrss.txt")
    full = ([gnu_time, "-f", "%M", "-o", rss_file] if gnu_time else []) + cmd
    # Output to a file, not a pipe: nobody reads a pipe while wait4() blocks.
    with tempfile.TemporaryFile(dir=tmp) as log:
        t0 = time.perf_counter()
        proc = subprocess.Popen(full, env=env, stdout=log, stderr=subprocess.STDOUT)
        _, status, ru = os.wait4(proc.pid, 0)  # rusage of the child and its reaped children
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            log.seek(0)
            raise RuntimeError(f"{' '.join(cmd)} exited with {proc.returncode}:\n{log.read().decode()}")
    maxrss = int(ru.ru_maxrss)
    if gnu_time:
        with open(rss_file) as f:
            maxrss = int(f.read().split()[-1])
    return wall, ru.ru_utime + ru.ru_stime, maxrss


def run_once(binary, tmp, n, threads, steps, trajectories=False):
    """One `wavefuel run`; returns the figures of the run. Raises on a failed run (never a silent zero)."""
    out = os.path.join(tmp, f"scaling_{n}_{threads}.h5")
    cmd = [binary, "run", SCENARIO, "-q", "--force", "-o", out, "--threads", str(threads),
           "--set", f"fleet.vehicles={n}", "--set", f"road.length_m={SPACING_M * n:.17g}",
           "--set", f"time.duration_s={steps * DT_S:.10g}"]
    if trajectories:
        cmd += ["--set", "output.trajectories=true"]
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    wall_proc, cpu_s, maxrss_kib = timed_child(cmd, tmp, env)
    with h5py.File(out) as f:
        m = f["meta"]
        names = [x.decode() if isinstance(x, bytes) else str(x) for x in m["phase_name"][()]]
        phases = dict(zip(names, (float(x) for x in m["phase_time"][()])))
        r = dict(n=n, threads=int(m["threads"][()]), steps=int(m["steps_done"][()]), loop_s=float(m["wall_time_s"][()]),
                 proc_s=wall_proc, cpu_s=cpu_s, maxrss_kib=maxrss_kib, phases=phases,
                 trajectories=trajectories, git_hash=m["git_hash"][()].decode(), file_bytes=os.path.getsize(out))
    os.unlink(out)
    if r["threads"] != threads or r["steps"] != steps:
        raise RuntimeError(f"run of N={n}: asked {threads} threads / {steps} steps, file says "
                           f"{r['threads']} / {r['steps']}")
    r["vsteps_per_s"] = n * r["steps"] / r["loop_s"]
    r["vsteps_per_s_process"] = n * r["steps"] / r["proc_s"]
    return r


def measure(binary, tmp, n, threads, repeats, kind, trajectories=False, log=print):
    steps = steps_for(n)
    load0 = loadavg()
    runs = [run_once(binary, tmp, n, threads, steps, trajectories) for _ in range(repeats)]
    load1 = loadavg()
    best = min(runs, key=lambda r: r["loop_s"])
    cfg = dict(kind=kind, n=n, threads=threads, steps=steps, repeats=repeats, trajectories=trajectories,
               loop_s=best["loop_s"], proc_s=min(r["proc_s"] for r in runs),
               vsteps_per_s=best["vsteps_per_s"], vsteps_per_s_process=max(r["vsteps_per_s_process"] for r in runs),
               maxrss_kib=max(r["maxrss_kib"] for r in runs), phases=best["phases"],
               file_bytes=best["file_bytes"], load_before=load0, load_after=load1, runs=runs)
    log(f"{kind:8s} N={n:>9d} threads={threads} steps={steps:>6d}  loop {best['loop_s']:8.3f} s  "
        f"{best['vsteps_per_s']:.3e} veh-steps/s  process {cfg['proc_s']:7.2f} s  RSS {cfg['maxrss_kib'] / 1024:8.1f} MiB"
        f"  load {load0:.2f}->{load1:.2f}")
    return cfg


def run_triad(log=print):
    exe = os.path.join(ROOT, "build", "bench", "stream_triad")
    mk = subprocess.run(["make", "--no-print-directory", "-C", ROOT, "build/bench/stream_triad"],
                        capture_output=True, text=True)
    if mk.returncode != 0:
        if not os.path.exists(exe):
            log(f"triad    not built (make build/bench/stream_triad failed), roofline skipped:\n{mk.stderr}")
            return None
        log("triad    make failed; using the existing build/bench/stream_triad")
    best = {}
    load0 = loadavg()
    for _ in range(3):
        out = subprocess.run([exe], check=True, capture_output=True, text=True).stdout.splitlines()
        for row in csv.DictReader(out):
            t = int(row["threads"])
            gbs = float(row["gb_per_s"])
            if t not in best or gbs > best[t]["gb_per_s"]:
                best[t] = dict(threads=t, n=int(row["n"]), gb_per_s=gbs,
                               gb_per_s_write_allocate=float(row["gb_per_s_write_allocate"]))
    res = dict(load_before=load0, load_after=loadavg(), rows=[best[t] for t in sorted(best)])
    for r in res["rows"]:
        log(f"triad    threads={r['threads']}  {r['gb_per_s']:.2f} GB/s (24 B/element; "
            f"{r['gb_per_s_write_allocate']:.2f} GB/s counting the write-allocate read)")
    return res


def cfg_lookup(res, kind, n, threads):
    for c in res["configs"]:
        if c["kind"] == kind and c["n"] == n and c["threads"] == threads:
            return c
    return None


def fmt_n(n):
    """22 -> 22, 1000000 -> 1e6, 2000000 -> 2e6."""
    if n < 1000:
        return str(n)
    m, e = f"{n:.0e}".split("e")
    return f"{m}e{int(e)}" if float(m) * 10 ** int(e) == n else str(n)


def fmt_rate(x):
    return f"{x:.3g}" if x is not None else "—"


def tables(res):
    """The Markdown tables of a results.json."""
    out = []
    m = res["machine"]
    out.append(f"Machine: {m['cpu']}, {m['cores']} cores, {m['compiler']}; wavefuel {res['git_hash']} "
               f"(binary sha256 {res['binary_sha256'][:12]}); {res['date']}; sweep {res['sweep_s'] / 60:.1f} min; "
               f"best of {res['repeats']}" + (f" (N = 1e7: best of {res['repeats_large']})" if res.get("repeats_large") else "")
               + ".")
    out.append("")
    out.append("**Throughput and strong scaling** (vehicle-steps/s of the step loop, energy, statistics and output "
               "included; process = the same over the whole process wall, setup and HDF5 included)")
    out.append("")
    out.append("| N | steps | 1 thread | 2 threads | speedup | efficiency | process, 1 thr | process, 2 thr | "
               "load (1 min) |")
    out.append("|---|---|---|---|---|---|---|---|---|")
    sizes = sorted({c["n"] for c in res["configs"] if c["kind"] == "strong"})
    for n in sizes:
        c1, c2 = cfg_lookup(res, "strong", n, 1), cfg_lookup(res, "strong", n, 2)
        sp = c1["loop_s"] / c2["loop_s"] if c1 and c2 else None
        loads = ", ".join(f"{c['load_before']:.1f}–{c['load_after']:.1f}" for c in (c1, c2) if c)
        cells = [fmt_n(n), str((c1 or c2)["steps"]), fmt_rate(c1 and c1["vsteps_per_s"]),
                 fmt_rate(c2 and c2["vsteps_per_s"]), f"{sp:.2f}" if sp else "—", f"{50 * sp:.0f} %" if sp else "—",
                 fmt_rate(c1 and c1["vsteps_per_s_process"]), fmt_rate(c2 and c2["vsteps_per_s_process"]), loads]
        out.append("| " + " | ".join(cells) + " |")
    weak = [c for c in res["configs"] if c["kind"] == "weak"]
    if weak:
        out.append("")
        out.append("**Weak scaling** (N per thread fixed: N on 1 thread against 2N on 2 threads; efficiency = "
                   "T(N, 1 thread) / T(2N, 2 threads) at equal steps)")
        out.append("")
        out.append("| N per thread | 1 thread: loop s | 2 threads: loop s | veh-steps/s 1 thr | veh-steps/s 2 thr | "
                   "efficiency | load |")
        out.append("|---|---|---|---|---|---|---|")
        for c2 in sorted(weak, key=lambda c: c["n"]):
            c1 = cfg_lookup(res, "strong", c2["n"] // 2, 1)
            if not c1 or c1["steps"] != c2["steps"]:
                continue
            out.append(f"| {fmt_n(c2['n'] // 2)} | {c1['loop_s']:.3f} | {c2['loop_s']:.3f} | "
                       f"{fmt_rate(c1['vsteps_per_s'])} | {fmt_rate(c2['vsteps_per_s'])} | "
                       f"{100 * c1['loop_s'] / c2['loop_s']:.0f} % | {c2['load_before']:.1f}–{c2['load_after']:.1f} |")
    base = cfg_lookup(res, "strong", 22, 1)
    out.append("")
    out.append("**Memory** (peak RSS of the process / N; marginal = (RSS − RSS at N = 22) / N"
               + (f", RSS at N = 22: {base['maxrss_kib'] / 1024:.1f} MiB" if base else "") + ")")
    out.append("")
    out.append("| N | threads | trajectories | peak RSS (MiB) | bytes/vehicle | marginal bytes/vehicle | "
               "result file (MB) |")
    out.append("|---|---|---|---|---|---|---|")
    memrows = [c for c in res["configs"] if c["n"] >= 100_000 and c["kind"] in ("strong", "traj")]
    for c in sorted(memrows, key=lambda c: (c["n"], c["trajectories"], c["threads"])):
        rss = c["maxrss_kib"] * 1024
        marg = (rss - base["maxrss_kib"] * 1024) / c["n"] if base else float("nan")
        out.append(f"| {fmt_n(c['n'])} | {c['threads']} | {'on' if c['trajectories'] else 'off'} | {rss / 2**20:.1f} | "
                   f"{rss / c['n']:.0f} | {marg:.0f} | {c['file_bytes'] / 1e6:.1f} |")
    trajs = [c for c in res["configs"] if c["kind"] == "traj"]
    if trajs:
        out.append("")
        out.append("**Trajectory output overhead** (every output interval, 1 s = 10 steps; same steps as above)")
        out.append("")
        out.append("| N | threads | veh-steps/s, trajectories off | on | output phase share (on) | load |")
        out.append("|---|---|---|---|---|---|")
        for c in sorted(trajs, key=lambda c: c["n"]):
            off = cfg_lookup(res, "strong", c["n"], c["threads"])
            share = c["phases"].get("output", 0.0) / c["loop_s"]
            out.append(f"| {fmt_n(c['n'])} | {c['threads']} | {fmt_rate(off and off['vsteps_per_s'])} | "
                       f"{fmt_rate(c['vsteps_per_s'])} | {100 * share:.1f} % | "
                       f"{c['load_before']:.1f}–{c['load_after']:.1f} |")
    names = []
    for c in res["configs"]:
        names += [k for k in c["phases"] if k not in names]
    out.append("")
    out.append("**Time per phase** (share of the step-loop wall of the best run; "
               "ns per vehicle-step in brackets)")
    out.append("")
    out.append("| N | threads | " + " | ".join(names) + " | sum of phases / loop wall |")
    out.append("|---|---|" + "---|" * len(names) + "---|")
    for c in sorted((c for c in res["configs"] if c["kind"] == "strong"), key=lambda c: (c["n"], c["threads"])):
        vs = c["n"] * c["steps"]
        cells = [f"{100 * c['phases'].get(k, 0.0) / c['loop_s']:.1f} % ({1e9 * c['phases'].get(k, 0.0) / vs:.2f})"
                 for k in names]
        out.append(f"| {fmt_n(c['n'])} | {c['threads']} | " + " | ".join(cells) +
                   f" | {100 * sum(c['phases'].values()) / c['loop_s']:.1f} % |")
    tri = res.get("triad")
    if tri:
        out.append("")
        bw = {r["threads"]: r["gb_per_s_write_allocate"] for r in tri["rows"]}
        out.append("**Roofline** (STREAM triad, best of 3 x 10, DRAM traffic counted with the write-allocate read, "
                   "32 B per element: " +
                   ", ".join(f"{bw[t]:.1f} GB/s on {t} thread{'s' if t > 1 else ''}" for t in sorted(bw)) +
                   f"; load {tri['load_before']:.1f}–{tri['load_after']:.1f})")
        incache = cfg_lookup(res, "strong", IN_CACHE_N, 1)
        out.append("")
        out.append(f"Memory bound = triad bandwidth / {BYTES_PER_VSTEP} B per vehicle-step (bench/README.md); "
                   f"compute bound = the in-cache rate (N = {fmt_n(IN_CACHE_N)}, 1 thread, working set inside L2) "
                   "x threads; the roofline bound is the lower of the two.")
        out.append("")
        out.append("| N | threads | memory bound | compute bound | measured | fraction of the bound | "
                   "fraction of the memory bound | DRAM traffic implied (GB/s) |")
        out.append("|---|---|---|---|---|---|---|---|")
        for n in (1_000_000, 10_000_000):
            for t in sorted(bw):
                c = cfg_lookup(res, "strong", n, t)
                if not c:
                    continue
                mem = bw[t] * 1e9 / BYTES_PER_VSTEP
                cpu = incache["vsteps_per_s"] * t if incache else float("inf")
                bound = min(mem, cpu)
                out.append(f"| {fmt_n(n)} | {t} | {mem:.3g} | {fmt_rate(incache and cpu)} | {c['vsteps_per_s']:.3g} | "
                           f"{100 * c['vsteps_per_s'] / bound:.0f} % | {100 * c['vsteps_per_s'] / mem:.1f} % | "
                           f"{c['vsteps_per_s'] * BYTES_PER_VSTEP / 1e9:.2f} |")
    return "\n".join(out)


def write_csv(res, path):
    names = []
    for c in res["configs"]:
        names += [k for k in c["phases"] if k not in names]
    cols = ["kind", "n", "threads", "steps", "repeats", "trajectories", "loop_s", "proc_s", "vsteps_per_s",
            "vsteps_per_s_process", "maxrss_kib", "bytes_per_vehicle", "file_bytes", "load_before", "load_after"]
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols + [f"phase_{k}_s" for k in names])
        for c in res["configs"]:
            row = [c[k] if k != "bytes_per_vehicle" else c["maxrss_kib"] * 1024 / c["n"] for k in cols]
            w.writerow([f"{x:.6g}" if isinstance(x, float) else x for x in row] +
                       [f"{c['phases'].get(k, 0.0):.6g}" for k in names])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.path.join(ROOT, "bin", "wavefuel"))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--repeats-large", type=int, default=None, metavar="R",
                    help="repeats at N >= 1e7, where setup takes minutes (default: --repeats)")
    ap.add_argument("--sizes", default=",".join(str(n) for n in SIZES))
    ap.add_argument("--out", default=HERE, help="directory for results.json and results.csv")
    ap.add_argument("--no-triad", action="store_true", help="skip the STREAM triad")
    ap.add_argument("--no-memory", action="store_true", help="skip the trajectory-on memory runs")
    ap.add_argument("--no-weak", action="store_true", help="skip the weak-scaling runs")
    ap.add_argument("--table", nargs="?", const=os.path.join(HERE, "results.json"), metavar="RESULTS_JSON",
                    help="only print the tables of an existing results.json")
    args = ap.parse_args()
    if args.table:
        with open(args.table) as f:
            print(tables(json.load(f)))
        return 0
    # The copied binary finds no vehicle classes beside itself: name the checkout's (docs/energy.md).
    os.environ.setdefault("WAVEFUEL_VEHICLES", os.path.join(ROOT, "vehicles"))
    sizes = [int(float(s)) for s in args.sizes.split(",")]
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="wf_scaling_", dir=os.environ.get("TMPDIR", "/tmp")) as tmp:
        binary = os.path.join(tmp, "wavefuel")
        shutil.copy2(args.bin, binary)
        res = dict(date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%MZ"), machine=machine("compiler", ["gcc", "--version"], "unknown"),
                   binary_sha256=sha256(binary), repeats=args.repeats, repeats_large=args.repeats_large, scenario=os.path.relpath(SCENARIO, ROOT),
                   configs=[])
        print(f"# {res['date']}  {res['machine']['cpu']}, {res['machine']['cores']} cores; load {loadavg():.2f}",
              flush=True)
        if not args.no_triad:
            tri = run_triad(log=lambda s: print(s, flush=True))
            if tri:
                res["triad"] = tri
        log = lambda s: print(s, flush=True)  # noqa: E731
        reps = lambda n: args.repeats_large if args.repeats_large and n >= 10_000_000 else args.repeats  # noqa: E731
        for n in sizes:
            for t in (1, 2):
                res["configs"].append(measure(binary, tmp, n, t, reps(n), "strong", log=log))
        if not args.no_weak:
            for per in WEAK_PER_THREAD:
                if per in sizes:
                    res["configs"].append(measure(binary, tmp, 2 * per, 2, reps(2 * per), "weak", log=log))
        if not args.no_memory:
            # Memory is deterministic; one run each. The throughput with trajectories is the output overhead.
            for n in TRAJ_SIZES:
                if n in sizes:
                    res["configs"].append(measure(binary, tmp, n, 2, 1, "traj", trajectories=True, log=log))
        res["git_hash"] = res["configs"][0]["runs"][0]["git_hash"] if res["configs"] else "unknown"
    res["sweep_s"] = time.perf_counter() - t_start
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(res, f, indent=1)
    write_csv(res, os.path.join(args.out, "results.csv"))
    print()
    print(tables(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
