#!/usr/bin/python3
"""One road split across MPI ranks (issue 20, `mpirun -n R bin/wavefuel-mpi run`): weak and strong scaling over
R = 1, 2, 4 ranks of one thread each, on the ring of bench/scaling/ring.yaml (IDM with noise, two energy classes,
ballistic dt 0.1 s, a record every second, 25 m of road per vehicle), and the bit-identity check at 1e7 vehicles.

--road corridor: the corridor of bench/corridor_vs_ring/corridor.yaml (the same drivers and classes, fed above its
capacity, Edie cells of 500 m), --km-per-rank of road per rank (weak; strong: twice that on every R), simulated for
--fill times the time a vehicle at 25 m/s takes to cross the road, so that it fills and stays full; its vehicles
(N) are the mean of /timeseries/vehicles, its vehicle-steps N x steps. The identity check is that of its largest run.

  weak      N = --per-rank vehicles per rank (2.5e6: 1e7 at R = 4), --steps steps;
  strong    N = 2 x --per-rank (5e6) on R = 1, 2, 4 (R = 2 is the weak run of the same N);
  one-proc  `bin/wavefuel run` of --per-rank vehicles on one thread (the one-process rate the ranks are measured
            against) and of the 1e7 ring of the weak R = 4 run on 2 threads: every dataset outside /meta of the two
            files (and /meta/steps_done, /meta/completed) compared byte for byte.

Figures per run (one run each: the machine is shared, the 1-minute load average before and after is recorded):
vehicle-steps/s of the step loop (N x /meta/steps_done / /meta/wall_time_s of the file rank 0 writes) and over the
whole mpirun process (setup, the ranks' start and HDF5 included); peak RSS of every rank (GNU time %M wrapped around
each rank). With more ranks than cores (this machine has 2) the ranks are oversubscribed (--oversubscribe
--bind-to none): the R = 4 figures then measure time sharing, not 4 cores.

The binaries are copied once at the start (a rebuild during the runs cannot mix two versions); their SHA-256 and
/meta/git_hash are recorded. Results: bench/mpi_ring/results.json; the Markdown table is printed at the end, and by
--table from results.json.

Usage: /usr/bin/python3 bench/mpi_ring/run.py [--per-rank 2500000] [--steps 40] [--ranks 1,2,4] [--no-identity]
           [--bin bin/wavefuel] [--mpi-bin bin/wavefuel-mpi] [--out bench/mpi_ring/results.json] [--table [JSON]]
       /usr/bin/python3 bench/mpi_ring/run.py --road corridor [--km-per-rank 100] [--fill 1.5] [--ranks 1,2,4]
           [--block-steps K] [--set KEY=VALUE ...] [--out bench/mpi_ring/results_corridor.json]
--block-steps K sets time.block_steps of every run (a corridor steps one step at a time by default; split, it then
exchanges every step; in windows of K steps, K times less often: docs/mpi.md).
"""
import argparse
import datetime
import glob
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
SCENARIO = os.path.join(ROOT, "bench", "scaling", "ring.yaml")
CORRIDOR = os.path.join(ROOT, "bench", "corridor_vs_ring", "corridor.yaml")
sys.path.insert(0, os.path.join(ROOT, "tests"))
from h5same import compare  # noqa: E402 (the one comparison of two results)
SPACING_M = 25.0  # road per vehicle, as in ring.yaml
DT_S = 0.1
MPI_ENV = dict(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_btl_vader_single_copy_mechanism="none")


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for blk in iter(lambda: f.read(1 << 20), b""):
            h.update(blk)
    return h.hexdigest()


ROAD = dict(kind="ring", fill=1.5, block_steps=None, sets=[])  # set by main: the road of the runs


def scenario_args(n, steps):
    """A ring of n vehicles; a corridor of n metres, simulated for `steps` steps."""
    block = ["--set", f"time.block_steps={ROAD['block_steps']}"] if ROAD["block_steps"] else []
    for kv in ROAD["sets"]:
        block += ["--set", kv]
    if ROAD["kind"] == "corridor":
        return [CORRIDOR, "--set", f"road.length_m={n:.17g}", "--set", f"time.duration_s={steps * DT_S:.10g}"] + block
    return block + [SCENARIO, "--set", f"fleet.vehicles={n}", "--set", f"road.length_m={SPACING_M * n:.17g}",
            "--set", f"time.duration_s={steps * DT_S:.10g}"]


def corridor_steps(length_m):
    """Steps for a corridor of that length to fill (a vehicle at 25 m/s crosses it) and stay full, x --fill."""
    return int(round(ROAD["fill"] * length_m / 25.0 / DT_S))


def run_one(kind, ranks, n, steps, threads, bins, tmp, keep=None):
    """One run to completion (ranks = 0: `wavefuel run` in one process); returns its figures. Raises on failure."""
    out = keep or os.path.join(tmp, "r.h5")
    rss = os.path.join(tmp, "rss")
    for f in glob.glob(rss + ".*"):
        os.unlink(f)
    args = ["run"] + scenario_args(n, steps) + ["-o", out, "--force", "--threads", str(threads)]
    # Each process under GNU time, its peak RSS in rss.RANK (Open MPI names the rank in OMPI_COMM_WORLD_RANK).
    timed = ["/bin/sh", "-c", '/usr/bin/time -f %M -o "$0.${OMPI_COMM_WORLD_RANK:-0}" "$@"', rss]
    if ranks:
        cmd = ["mpirun", "-n", str(ranks), "--oversubscribe", "--bind-to", "none"] + timed + [bins["mpi"]] + args
    else:
        cmd = timed + [bins["one"]] + args
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), **MPI_ENV)
    if ROAD["kind"] == "corridor":  # it exchanges every step: a waiting rank gives its core to an oversubscribed one
        env["OMPI_MCA_mpi_yield_when_idle"] = "1"
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, env=env, capture_output=True, text=True)
    proc_s = time.perf_counter() - t0
    if p.returncode:
        raise RuntimeError(f"{' '.join(cmd)} exited with {p.returncode}:\n{p.stdout}\n{p.stderr}")
    rss_kib = []
    for r in range(max(ranks, 1)):
        with open(f"{rss}.{r}") as f:
            rss_kib.append(int(f.read().split()[-1]))
    header = next((line for line in p.stdout.splitlines() if "vehicle-steps/s" in line or "corridor" in line), "")
    with h5py.File(out) as f:
        m = f["meta"]
        if ROAD["kind"] == "corridor":  # its vehicles: the mean over the records
            n = int(round(float(f["timeseries/vehicles"][()].mean())))
        res = dict(kind=kind, ranks=ranks, n=n, threads=threads, steps=int(m["steps_done"][()]),
                   loop_s=float(m["wall_time_s"][()]), proc_s=proc_s, rss_kib=rss_kib,
                   git_hash=m["git_hash"][()].decode(), header=header, load_before=load0,
                   load_after=os.getloadavg()[0], file_bytes=os.path.getsize(out))
    if not keep:
        os.unlink(out)
    if res["steps"] != steps:
        raise RuntimeError(f"{kind} R={ranks} N={n}: asked {steps} steps, the file says {res['steps']}")
    if ranks and f"{threads} threads x {ranks} processes," not in header:
        raise RuntimeError(f"{kind} R={ranks}: the header does not say '{threads} threads x {ranks} processes':\n"
                           f"{p.stdout}")
    res["vsteps_per_s"] = n * res["steps"] / res["loop_s"]
    res["vsteps_per_s_process"] = n * res["steps"] / proc_s
    print(f"{kind:9s} R={ranks or '-'} N={n:>9d} threads={threads} steps={steps}  loop {res['loop_s']:7.3f} s  "
          f"{res['vsteps_per_s']:.3e} veh-steps/s  process {proc_s:6.2f} s  peak RSS per rank "
          f"{', '.join(f'{k / 1024:.0f}' for k in rss_kib)} MiB  load {load0:.2f}->{res['load_after']:.2f}", flush=True)
    return res


def fmt_n(n):
    """2500000 -> 2.5e6, 1250000 -> 1.25e6."""
    m, e = f"{n:.2e}".split("e")
    return f"{float(m):g}e{int(e)}"


def table(res):
    out = []
    m = res["machine"]
    steps = f"{res['steps']} steps of 0.1 s" if res.get("road", "ring") == "ring" else \
        f"a corridor of {res['per_rank'] / 1000:g} km per rank (N: its mean vehicles on the road), steps as the runs say"
    block = f"time.block_steps {res['block_steps']}; " if res.get("block_steps") else ""
    block += "".join(f"{kv}; " for kv in res.get("sets", []))
    out.append(f"Machine: {m['cpu']}, {m['cores']} cores ({m['mpi']}); wavefuel {res['git_hash']}; {res['date']}; "
               f"one run each; {steps}; {block}1 thread per rank; ranks beyond {m['cores']} are "
               "oversubscribed (--oversubscribe --bind-to none): they share the cores.")
    out.append("")
    out.append("| scaling | R | N | N per rank | loop s | veh-steps/s (loop) | per rank | efficiency | "
               "process s | veh-steps/s (process) | peak RSS per rank (MiB) | load |")
    out.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
    one = next((c for c in res["runs"] if c["kind"] == "one-proc" and c["threads"] == 1), None)
    weak1 = next((c for c in res["runs"] if c["kind"] == "weak" and c["ranks"] == 1), None)
    for c in res["runs"]:
        per = c["n"] // max(c["ranks"], 1)
        # rate of R ranks / (R x rate of 1 rank): for a ring's weak runs (equal steps) T(1 rank, N) / T(R, R N)
        if c["kind"] == "weak" and weak1:
            eff = f"{100 * c['vsteps_per_s'] / (c['ranks'] * weak1['vsteps_per_s']):.0f} %"
        elif c["kind"] == "strong":
            s1 = next((d for d in res["runs"] if d["n"] == c["n"] and d["ranks"] == 1), None)
            eff = f"{100 * c['vsteps_per_s'] / (c['ranks'] * s1['vsteps_per_s']):.0f} %" if s1 else "—"
        else:
            eff = "—"
        who = str(c["ranks"]) if c["ranks"] else f"1 process, {c['threads']} thr"
        out.append(f"| {c['kind']} | {who} | "
                   f"{fmt_n(c['n'])} | {fmt_n(per)} | {c['loop_s']:.2f} | {c['vsteps_per_s']:.3g} | "
                   f"{c['vsteps_per_s'] / max(c['ranks'], 1):.3g} | {eff} | {c['proc_s']:.1f} | "
                   f"{c['vsteps_per_s_process']:.3g} | {', '.join(f'{k / 1024:.0f}' for k in c['rss_kib'])} | "
                   f"{c['load_before']:.1f}–{c['load_after']:.1f} |")
    out.append("")
    out.append("Efficiency: veh-steps/s (loop) of R ranks / (R x that of 1 rank): weak, R times the road; strong, the "
               "same road (for a ring's runs of equal steps, loop time of 1 rank / loop time of R ranks, and / R "
               "for strong). Per rank = veh-steps/s / R.")
    if one:
        out.append(f"One process (`bin/wavefuel run`, 1 thread) at N = {fmt_n(one['n'])}: "
                   f"{one['vsteps_per_s']:.3g} veh-steps/s.")
    ident = res.get("identity")
    if ident:
        out.append("")
        out.append(f"Bit identity at N = {fmt_n(ident['n'])}: `mpirun -n {ident['ranks']} wavefuel-mpi run` against "
                   f"`wavefuel run` (one process, {ident['threads']} threads): {ident['datasets']} datasets outside "
                   f"/meta (and /meta/steps_done, /meta/completed) compared byte for byte: "
                   + ("**identical**." if not ident["differ"] else f"**differ**: {', '.join(ident['differ'][:10])}"))
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.path.join(ROOT, "bin", "wavefuel"))
    ap.add_argument("--mpi-bin", default=os.path.join(ROOT, "bin", "wavefuel-mpi"))
    ap.add_argument("--per-rank", type=float, default=2.5e6, help="vehicles per rank of the weak scaling")
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--ranks", default="1,2,4")
    ap.add_argument("--no-identity", action="store_true", help="skip the one-process run of the largest road")
    ap.add_argument("--road", choices=("ring", "corridor"), default="ring")
    ap.add_argument("--km-per-rank", type=float, default=100.0, help="a corridor's road per rank of the weak scaling")
    ap.add_argument("--fill", type=float, default=1.5, help="a corridor's simulated time, in crossing times")
    ap.add_argument("--block-steps", type=int, default=None,
                    help="time.block_steps of every run (default: the scenario's; a corridor's is 1, one step at a time)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a scenario key for every run (repeatable), as `wavefuel run --set`")
    ap.add_argument("--out", default=os.path.join(HERE, "results.json"))
    ap.add_argument("--table", nargs="?", const=os.path.join(HERE, "results.json"), metavar="RESULTS_JSON",
                    help="only print the table of an existing results.json")
    args = ap.parse_args()
    if args.table:
        with open(args.table) as f:
            print(table(json.load(f)))
        return 0
    os.environ.setdefault("WAVEFUEL_VEHICLES", os.path.join(ROOT, "vehicles"))  # the copies find no classes beside them
    per, ranks = int(args.per_rank), [int(r) for r in args.ranks.split(",")]
    ROAD.update(kind=args.road, fill=args.fill, block_steps=args.block_steps, sets=args.set)
    corridor = args.road == "corridor"
    if corridor:
        per = int(args.km_per_rank * 1000)  # metres of road per rank
        if args.out == os.path.join(HERE, "results.json"):
            args.out = os.path.join(HERE, "results_corridor.json")

    def steps(n):
        return corridor_steps(n) if corridor else args.steps
    res = dict(date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%MZ"), machine=machine("mpi", ["mpirun", "--version"], "unknown MPI"),
               scenario=os.path.relpath(CORRIDOR if corridor else SCENARIO, ROOT), road=args.road, per_rank=per,
               steps=args.steps, block_steps=args.block_steps, sets=args.set, runs=[])
    print(f"# {res['date']}  {res['machine']['cpu']}, {res['machine']['cores']} cores "
          f"(R > {res['machine']['cores']}: oversubscribed, the ranks share the cores); load {os.getloadavg()[0]:.2f}",
          flush=True)
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="wf_mpi_ring_", dir=os.environ.get("TMPDIR", "/tmp")) as tmp:
        bins = dict(one=os.path.join(tmp, "wavefuel"), mpi=os.path.join(tmp, "wavefuel-mpi"))
        shutil.copy2(args.bin, bins["one"])
        shutil.copy2(args.mpi_bin, bins["mpi"])
        res["binary_sha256"] = {k: sha256(v) for k, v in bins.items()}
        runs = res["runs"]
        runs.append(run_one("one-proc", 0, per, steps(per), 1, bins, tmp))
        big = os.path.join(tmp, "mpi_big.h5")
        for r in ranks:
            keep = big if r == max(ranks) and not args.no_identity else None
            runs.append(run_one("weak", r, per * r, steps(per * r), 1, bins, tmp, keep=keep))
        n_strong = 2 * per
        for r in ranks:
            if r * per != n_strong:  # R = 2 is the weak run of this N
                runs.append(run_one("strong", r, n_strong, steps(n_strong), 1, bins, tmp))
            else:
                runs.append(dict(next(c for c in runs if c["kind"] == "weak" and c["ranks"] == r), kind="strong"))
        if not args.no_identity:
            n_big = per * max(ranks)
            ref = os.path.join(tmp, "one_big.h5")
            runs.append(run_one("one-proc", 0, n_big, steps(n_big), 2, bins, tmp, keep=ref))
            count, bad = compare(ref, big)
            res["identity"] = dict(n=runs[-1]["n"], ranks=max(ranks), threads=2, datasets=count, differ=bad)
            print(f"identity  N={n_big}: {count} datasets outside /meta compared: "
                  + ("identical" if not bad else f"DIFFER: {bad[:10]}"), flush=True)
    res["git_hash"] = res["runs"][0]["git_hash"]
    res["total_s"] = time.perf_counter() - t_start
    with open(args.out, "w") as f:
        json.dump(res, f, indent=1)
    print()
    print(table(res))
    return 1 if res.get("identity", {}).get("differ") else 0


if __name__ == "__main__":
    sys.exit(main())
