#!/usr/bin/python3
"""wavefuel against SUMO on the same ring (issue 8), in one run, for N = 1e3, 1e4, 1e5.

The ring: one lane, 25 m of road per vehicle, IDM with v0 30 m/s, T 1 s, s0 (minGap) 2 m, a (accel) 1 m/s^2,
b (decel) 1.5 m/s^2, delta 4, length 5 m, no noise (sigma 0), dt 0.1 s, ballistic position update in both, every
vehicle at rest and evenly spaced at t = 0. SUMO's ring is a regular polygon of N/125 straight edges of 3125 m
(125 vehicles each; netconvert, no internal links, so the lap is exactly 25 N m); each vehicle's route runs once
round from its start edge and is repeated (route attribute `repeat`) for more laps than the run can drive. Both
are checked to simulate the same thing: the mean speed at t = 10 s and 50 s (SUMO --summary-output, wavefuel
/timeseries/mean_speed) is printed side by side.

Throughput is vehicle-steps per second of the simulation loop, best of --repeats. SUMO: from its "UPS" (vehicle
updates per second of its simulation loop, loading the network and routes excluded), with the first step, in which
SUMO inserts every vehicle, taken out (timed by 1-step runs), as wavefuel's loop excludes placing the vehicles.
wavefuel: N x /meta/steps_done / /meta/wall_time_s, over at least 5e7 vehicle-steps (same ring and dt, more steps
than SUMO runs: a 0.1 s run is spoilt by one burst of load on a shared machine). SUMO runs without and with its
emission device (HBEFA3/PC_G_EU4, the default class of SUMO 1.15, on every vehicle: --device.emissions.probability
1). wavefuel always evaluates its energy model, and its one-pass step does not time the energy apart (in
/meta/phase_time the energy phase stays 0): it is compared, fuel included, with SUMO without and with the device.

SUMO is optional: without `sumo` and `netconvert` on PATH the SUMO columns are skipped (and said so), and only
wavefuel runs. Writes bench/vs_sumo/results.json and results.csv; --table prints the Markdown table again.
Usage: /usr/bin/python3 bench/vs_sumo/run.py [--sizes 1000,10000,100000] [--repeats 3] [--bin bin/wavefuel]
                                             [--table [results.json]]
"""
import argparse
import csv
import datetime
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

import json
import h5py

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SCENARIO = os.path.join(HERE, "ring.yaml")
SPACING_M = 25.0
VEH_PER_EDGE = 125  # 3125 m edges: short lanes keep SUMO's per-lane insertion cheap
DT_S = 0.1
V0_MPS = 30.0
SIZES = [1000, 10_000, 100_000]
# 2e6 to 1e7 vehicle-steps: 5 to 60 s of SUMO per run. At 1e5 SUMO's first step (insertion) takes seconds: enough
# steps that subtracting it leaves a well-measured loop.
STEPS = {1000: 2000, 10_000: 500, 100_000: 100}
# wavefuel is ~100x faster: at SUMO's step counts a run would take 0.1 s, which one burst of load on a shared
# machine spoils (threads descheduled at a barrier). It runs the same ring and dt for at least 5e7 vehicle-steps.
WF_MIN_VSTEPS = 5e7
EMISSION_CLASS = "HBEFA3/PC_G_EU4"
CHECK_TIMES_S = (10.0, 50.0)


def loadavg():
    return os.getloadavg()[0]


def run_child(cmd, cwd, env=None):
    """Run cmd; return (stdout+stderr text, wall s, CPU s, peak RSS KiB). Raises on failure.

    Peak RSS from GNU time's %M when /usr/bin/time exists: the ru_maxrss of a child forked by this Python process
    starts at Python's own resident size (the high-water mark survives exec)."""
    gnu_time = shutil.which("time", path="/usr/bin")
    rss_file = os.path.join(cwd, "maxrss.txt")
    full = ([gnu_time, "-f", "%M", "-o", rss_file] if gnu_time else []) + list(cmd)
    with tempfile.TemporaryFile(dir=cwd) as log:
        t0 = time.perf_counter()
        proc = subprocess.Popen(full, cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT)
        _, status, ru = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        log.seek(0)
        text = log.read().decode(errors="replace")
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited with {code}:\n{text}")
    maxrss = int(ru.ru_maxrss)
    if gnu_time:
        with open(rss_file) as f:
            maxrss = int(f.read().split()[-1])
    return text, wall, ru.ru_utime + ru.ru_stime, maxrss


# ---------------------------------------------------------------- SUMO
def sumo_env():
    env = dict(os.environ)
    if "SUMO_HOME" not in env and os.path.isdir("/usr/share/sumo"):
        env["SUMO_HOME"] = "/usr/share/sumo"  # Debian's location; SUMO warns without it
    return env


def write_sumo_ring(d, n, steps):
    """Network and routes of the ring of n vehicles in directory d; returns the lap length (m)."""
    k_edges = n // VEH_PER_EDGE
    if k_edges * VEH_PER_EDGE != n or k_edges < 3:
        raise ValueError(f"N = {n}: the SUMO ring needs N a multiple of {VEH_PER_EDGE} and >= {3 * VEH_PER_EDGE}")
    lap = SPACING_M * n
    edge = lap / k_edges
    r = lap / (2 * math.pi)  # node positions only draw the polygon; each edge's length is set explicitly
    with open(os.path.join(d, "ring.nod.xml"), "w") as f:
        f.write("<nodes>\n")
        for k in range(k_edges):
            a = 2 * math.pi * k / k_edges
            f.write(f'  <node id="n{k}" x="{r * math.cos(a):.3f}" y="{r * math.sin(a):.3f}" type="priority"/>\n')
        f.write("</nodes>\n")
    with open(os.path.join(d, "ring.edg.xml"), "w") as f:
        f.write("<edges>\n")
        for k in range(k_edges):
            # Lane speed 40 m/s > v0: the desired speed is the vType's maxSpeed (30 m/s), speedFactor 1.
            f.write(f'  <edge id="e{k}" from="n{k}" to="n{(k + 1) % k_edges}" numLanes="1" speed="40" '
                    f'length="{edge:.3f}"/>\n')
        f.write("</edges>\n")
    subprocess.run(["netconvert", "--xml-validation", "never", "-n", "ring.nod.xml", "-e", "ring.edg.xml",
                    "-o", "ring.net.xml", "--no-internal-links", "--no-turnarounds"], cwd=d, env=sumo_env(),
                   check=True, capture_output=True)
    laps = math.ceil(V0_MPS * steps * DT_S / lap) + 2
    with open(os.path.join(d, "ring.rou.xml"), "w") as f:
        f.write("<routes>\n")
        f.write('  <vType id="idm" carFollowModel="IDM" accel="1" decel="1.5" emergencyDecel="9" sigma="0" tau="1" '
                f'minGap="2" length="5" maxSpeed="{V0_MPS:g}" delta="4" speedFactor="1" speedDev="0" '
                f'emissionClass="{EMISSION_CLASS}"/>\n')
        for k in range(k_edges):
            edges = " ".join(f"e{(k + j) % k_edges}" for j in range(k_edges))
            f.write(f'  <route id="r{k}" edges="{edges}" repeat="{laps}"/>\n')
        # Front bumpers at 12.5 m, 37.5 m, ... of each edge (the whole vehicle on its edge). Within an edge the
        # vehicles are listed front first: SUMO then finds each new one's place at the start of its lane's list.
        for k in range(k_edges):
            for j in reversed(range(VEH_PER_EDGE)):
                f.write(f'  <vehicle id="v{k}_{j}" type="idm" route="r{k}" depart="0" '
                        f'departPos="{SPACING_M * j + SPACING_M / 2:.3f}" departSpeed="0" departLane="0"/>\n')
        f.write("</routes>\n")
    return lap


def sumo_cmd(steps, fuel, extra=()):
    cmd = ["sumo", "--xml-validation", "never", "-n", "ring.net.xml", "-r", "ring.rou.xml", "--step-length",
           f"{DT_S:g}", "--end", f"{steps * DT_S:.10g}", "--step-method.ballistic", "true", "--no-step-log",
           "--duration-log.statistics", "--time-to-teleport", "-1", "--seed", "1"]
    if fuel:
        cmd += ["--device.emissions.probability", "1"]
    return cmd + list(extra)


def parse_sumo(text, n):
    def grab(key):
        m = re.search(rf"^\s*{key}:\s*([-0-9.e+]+)", text, re.M)
        if not m:
            raise RuntimeError(f"SUMO output without '{key}':\n{text}")
        return float(m.group(1))
    ups, inserted = grab("UPS"), grab("Inserted")
    if inserted != n:
        raise RuntimeError(f"SUMO inserted {inserted:g} of {n} vehicles:\n{text}")
    for bad in ("Teleports", "Collisions"):
        m = re.search(rf"^\s*{bad}:\s*(\d+)", text, re.M)
        if m and int(m.group(1)):
            raise RuntimeError(f"SUMO run had {bad.lower()}:\n{text}")
    return ups


def sumo_measure(d, n, steps, fuel, repeats, first_step_s=0.0):
    """Best of repeats. ups is SUMO's figure (first step, i.e. insertion, included); vsteps_per_s excludes the
    first step: N (steps - 1) / (loop - first_step_s), first_step_s timed by a 1-step run (wavefuel's loop
    likewise excludes placing the vehicles)."""
    best = None
    for _ in range(repeats):
        text, wall, cpu, rss = run_child(sumo_cmd(steps, fuel), d, sumo_env())
        ups = parse_sumo(text, n)
        loop = n * steps / ups  # SUMO's Duration, recovered from UPS = vehicle updates / Duration
        r = dict(ups=ups, loop_s=loop, proc_s=wall, cpu_s=cpu, maxrss_kib=rss,
                 vsteps_per_s=n * (steps - 1) / (loop - first_step_s) if steps > 1 else ups)
        if best is None or loop < best["loop_s"]:
            best = r
    return best


def sumo_mean_speeds(d, n, times):
    """Mean speed at the given times from a run with the summary output (not timed)."""
    steps = int(round(max(times) / DT_S)) + 1
    run_child(sumo_cmd(steps, False, ["--summary-output", "summary.xml", "--precision", "6"]), d, sumo_env())
    with open(os.path.join(d, "summary.xml")) as f:
        text = f.read()
    # SUMO's record at time t is the state at t, as wavefuel's (checked: at N = 1000 both give 0.099000 m/s at
    # t = 0.1 s and 8.672027 m/s at 9.9 s).
    rec = {round(float(t), 6): float(v) for t, v in
           re.findall(r'<step time="([-0-9.e+]+)"[^>]*meanSpeed="([-0-9.e+]+)"', text)}
    out = {}
    for t in times:
        if round(t, 6) not in rec:
            raise RuntimeError(f"no summary record at t = {t:g} s in {d}/summary.xml")
        out[t] = rec[round(t, 6)]
    return out


# ---------------------------------------------------------------- wavefuel
def wavefuel_run(binary, d, n, steps, threads, extra=()):
    out = os.path.join(d, "wf.h5")
    cmd = [binary, "run", SCENARIO, "-q", "--force", "-o", out, "--threads", str(threads),
           "--set", f"fleet.vehicles={n}", "--set", f"road.length_m={SPACING_M * n:.17g}",
           "--set", f"time.duration_s={steps * DT_S:.10g}"]
    for s in extra:
        cmd += ["--set", s]
    _, wall, cpu, rss = run_child(cmd, d, dict(os.environ, OMP_NUM_THREADS=str(threads)))
    with h5py.File(out) as f:
        m = f["meta"]
        names = [x.decode() if isinstance(x, bytes) else str(x) for x in m["phase_name"][()]]
        r = dict(loop_s=float(m["wall_time_s"][()]), steps=int(m["steps_done"][()]), proc_s=wall, cpu_s=cpu,
                 maxrss_kib=rss, phases=dict(zip(names, (float(x) for x in m["phase_time"][()]))),
                 git_hash=m["git_hash"][()].decode())
        t, v = f["timeseries/t"][:], f["timeseries/mean_speed"][:]
        r["mean_speed"] = {tt: float(v[abs(t - tt) < 1e-9][0]) for tt in CHECK_TIMES_S if (abs(t - tt) < 1e-9).any()}
    os.unlink(out)
    if r["steps"] != steps:
        raise RuntimeError(f"wavefuel N={n}: {r['steps']} steps done, {steps} asked")
    r["vsteps_per_s"] = n * steps / r["loop_s"]
    return r


def wavefuel_measure(binary, d, n, steps, threads, repeats, extra=()):
    runs = [wavefuel_run(binary, d, n, steps, threads, extra) for _ in range(repeats)]
    return min(runs, key=lambda r: r["loop_s"])


# ---------------------------------------------------------------- table
def fmt(x, spec=".3g"):
    return format(x, spec) if x is not None else "—"


def fmt_n(n):
    """1000 -> 1e3; sizes that are not a power of ten stay in full."""
    e = round(math.log10(n)) if n > 0 else 0
    return f"1e{e}" if 10 ** e == n else str(n)


def tables(res):
    out = [f"{res['date']}: {res['machine']}; wavefuel {res['git_hash']}; {res['sumo_version'] or 'SUMO absent'}; "
           f"best of {res['repeats']}; whole run {res['total_s'] / 60:.1f} min. Vehicle-steps/s of the simulation "
           "loop; SUMO's first step (inserting every vehicle) excluded, as wavefuel's setup is (SUMO's own UPS, "
           "first step included, in results.json)."]
    if not res["sumo_version"]:
        out.append("")
        out.append("`sumo` / `netconvert` not on PATH: SUMO columns skipped (Debian: `apt-get install sumo`).")
    out.append("")
    out.append("| N | steps SUMO / wavefuel | SUMO | SUMO + emissions | wavefuel 1 thr | wavefuel 2 thr | ratio 1 thr / SUMO | "
               "ratio 1 thr / SUMO + emissions | ratio 2 thr / SUMO + emissions | load (1 min) |")
    out.append("|---|---|---|---|---|---|---|---|---|---|")
    for r in res["rows"]:
        s0, s1 = r.get("sumo"), r.get("sumo_fuel")
        w1, w2 = r["wf1"]["vsteps_per_s"], r["wf2"]["vsteps_per_s"]
        cells = [fmt_n(r["n"]), f"{r['steps']} / {r.get('wf_steps', r['steps'])}", fmt(s0 and s0["vsteps_per_s"]),
                 fmt(s1 and s1["vsteps_per_s"]), fmt(w1), fmt(w2),
                 fmt(s0 and w1 / s0["vsteps_per_s"], ".0f"), fmt(s1 and w1 / s1["vsteps_per_s"], ".0f"),
                 fmt(s1 and w2 / s1["vsteps_per_s"], ".0f"), f"{r['load_before']:.1f}–{r['load_after']:.1f}"]
        out.append("| " + " | ".join(cells) + " |")
    out.append("")
    out.append("wavefuel's rates include its energy model, which cannot be switched off. What SUMO's emission device "
               "costs SUMO (its loop time with the device over without):")
    out.append("")
    out.append("| N | SUMO: emission device cost |")
    out.append("|---|---|")
    for r in res["rows"]:
        s0, s1 = r.get("sumo"), r.get("sumo_fuel")
        cost = (s0["vsteps_per_s"] / s1["vsteps_per_s"] - 1.0) if s0 and s1 else None
        out.append(f"| {fmt_n(r['n'])} | {format(100 * cost, '+.0f') + ' % time' if cost is not None else '—'} |")
    out.append("")
    out.append("Same dynamics (mean speed, m/s; SUMO --summary-output, wavefuel /timeseries/mean_speed), and the "
               "cost of SUMO's first step (insertion of all vehicles, included in its UPS) and process figures:")
    out.append("")
    out.append("| N | " + " | ".join(f"t = {t:g} s: SUMO / wavefuel" for t in CHECK_TIMES_S) +
               " | SUMO first step (s) | SUMO process wall / peak RSS | wavefuel process wall / peak RSS (1 thr) |")
    out.append("|---|" + "---|" * len(CHECK_TIMES_S) + "---|---|---|")
    for r in res["rows"]:
        ms = r.get("sumo_mean_speed") or {}
        wm = r["wf1"]["mean_speed"]
        cells = [(f"{ms[str(t)]:.6f}" if str(t) in ms else "—") + " / " + (f"{wm[str(t)]:.6f}" if str(t) in wm else "—")
                 for t in CHECK_TIMES_S]
        s0 = r.get("sumo")
        out.append(f"| {fmt_n(r['n'])} | " + " | ".join(cells) + f" | {fmt(r.get('sumo_first_step_s'))} | " +
                   (f"{s0['proc_s']:.1f} s / {s0['maxrss_kib'] / 1024:.0f} MiB" if s0 else "—") +
                   f" | {r['wf1']['proc_s']:.2f} s / {r['wf1']['maxrss_kib'] / 1024:.0f} MiB |")
    return "\n".join(out)


def json_keys(x):
    """JSON object keys are strings: mean-speed dicts keyed by time are stored as str(t)."""
    if isinstance(x, dict):
        return {str(k): json_keys(v) for k, v in x.items()}
    if isinstance(x, list):
        return [json_keys(v) for v in x]
    return x


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.path.join(ROOT, "bin", "wavefuel"))
    ap.add_argument("--sizes", default=",".join(str(n) for n in SIZES))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=HERE)
    ap.add_argument("--table", nargs="?", const=os.path.join(HERE, "results.json"), metavar="RESULTS_JSON")
    args = ap.parse_args()
    if args.table:
        with open(args.table) as f:
            print(tables(json.load(f)))
        return 0
    have_sumo = shutil.which("sumo") and shutil.which("netconvert")
    sumo_version = None
    if have_sumo:
        v = subprocess.run(["sumo", "--version"], capture_output=True, text=True, env=sumo_env()).stdout
        sumo_version = v.splitlines()[0].strip() if v else "sumo (version unknown)"
    else:
        print("sumo/netconvert not found on PATH: SUMO runs skipped, wavefuel only (Debian: apt-get install sumo)",
              flush=True)
    cpu = next((ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name")), "?")
    res = dict(date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%MZ"),
               machine=f"{cpu}, {os.cpu_count()} cores", sumo_version=sumo_version, repeats=args.repeats, rows=[])
    # The copied binary finds no vehicle classes beside itself: name the checkout's (docs/energy.md).
    os.environ.setdefault("WAVEFUEL_VEHICLES", os.path.join(ROOT, "vehicles"))
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="wf_vs_sumo_") as tmp:
        binary = os.path.join(tmp, "wavefuel")
        shutil.copy2(args.bin, binary)  # one binary for the whole run, whatever gets rebuilt meanwhile
        for n in (int(float(s)) for s in args.sizes.split(",")):
            steps = STEPS.get(n, max(10, int(1e7 // n)))
            d = os.path.join(tmp, f"n{n}")
            os.makedirs(d)
            row = dict(n=n, steps=steps, load_before=loadavg())
            if have_sumo:
                row["lap_m"] = write_sumo_ring(d, n, steps)
                # The dynamics check costs a SUMO run to 50 s: done where that is at most 5e6 vehicle-steps.
                if n * max(CHECK_TIMES_S) / DT_S <= 5e6:
                    row["sumo_mean_speed"] = sumo_mean_speeds(d, n, CHECK_TIMES_S)
                row["sumo_first_step_s"] = sumo_measure(d, n, 1, False, args.repeats)["loop_s"]
                row["sumo_first_step_fuel_s"] = sumo_measure(d, n, 1, True, args.repeats)["loop_s"]
                row["sumo"] = sumo_measure(d, n, steps, False, args.repeats, row["sumo_first_step_s"])
                row["sumo_fuel"] = sumo_measure(d, n, steps, True, args.repeats, row["sumo_first_step_fuel_s"])
            row["wf_steps"] = wf_steps = max(steps, math.ceil(WF_MIN_VSTEPS / n))
            row["wf1"] = wavefuel_measure(binary, d, n, wf_steps, 1, args.repeats)
            row["wf2"] = wavefuel_measure(binary, d, n, wf_steps, 2, args.repeats)
            row["load_after"] = loadavg()
            res["rows"].append(row)
            s = row.get("sumo")
            print(f"N={n:>7d} steps={steps:>5d}  SUMO {fmt(s and s['vsteps_per_s'])}  SUMO+emissions "
                  f"{fmt(row.get('sumo_fuel') and row['sumo_fuel']['vsteps_per_s'])}  wavefuel 1 thr "
                  f"{row['wf1']['vsteps_per_s']:.3g}  2 thr {row['wf2']['vsteps_per_s']:.3g} veh-steps/s  load "
                  f"{row['load_before']:.2f}->{row['load_after']:.2f}", flush=True)
        res["git_hash"] = res["rows"][0]["wf1"]["git_hash"] if res["rows"] else "unknown"
    res["total_s"] = time.perf_counter() - t_start
    res = json_keys(res)
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(res, f, indent=1)
    with open(os.path.join(args.out, "results.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["n", "steps", "wavefuel_steps", "sumo_vsteps_per_s", "sumo_emissions_vsteps_per_s", "wavefuel_1t_vsteps_per_s",
                    "wavefuel_2t_vsteps_per_s", "sumo_first_step_s", "load_before", "load_after"])
        for r in res["rows"]:
            g = lambda k: r[k]["vsteps_per_s"] if k in r else ""  # noqa: E731
            w.writerow([r["n"], r["steps"], r["wf_steps"], g("sumo"), g("sumo_fuel"), g("wf1"), g("wf2"),
                        r.get("sumo_first_step_s", ""), r["load_before"], r["load_after"]])
    print()
    print(tables(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
