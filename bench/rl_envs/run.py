#!/usr/bin/python3
"""Environment steps per second of wavefuel's VectorEnv (issue 17), side by side in one run with the numpy baseline
(numpy_ring.py, the same ring environment vectorised over environments in numpy):

1. agreement: B rings of wavefuel's VectorEnv and of the baseline from the same state (copied from wavefuel's
   environments after their reset), without noise (the two generators differ), the same commands (a gap-keeping
   law of the observations, which never collides: the baseline has no overlap repair), for --check-steps
   steps: the largest differences of positions, speeds and rewards are printed (the comparison is fair only if they
   are small; the run fails above 1e-6 m, 1e-6 m/s or 1e-9 relative);
2. rings: --envs rings of 22 vehicles (1 automated, RingEnv's defaults: IDM humans with 0.2 m/s^2 noise, ring
   length drawn in [220, 270] m, dt 0.1 s, an action every step), a constant action (0 m/s^2): env-steps per
   second = envs x steps / time of the step calls, wall and CPU (the process's, all threads), best of --repeats
   (each repeat times every case in turn), and the median over the repeats of the baseline's time / the case's in
   the same repeat, for VectorEnv on 1 thread, on 2 threads (its thread governor choosing
   each action's count: the default) and on 2 threads always (thread_check=0), and the baseline; no episode ends
   inside the timed steps (horizon 1e4 s), resets are timed apart; --load adds two CPU-bound processes beside
   every timed case (busy loops that stop themselves after 600 s and are killed at the end);
3. trajectories: --envs TrajectoryEnvs of 200 vehicles (an automated vehicle after every 4 humans, 40 a platoon)
   behind a leader replaying a synthetic stop-and-go trace, the same three VectorEnv cases.

4. SUMO + TraCI (the issue's second comparison; sumo_ring.py: the same rings, --envs lengths, in SUMO, one SUMO
   simulation per environment as Flow runs them, the automated vehicle commanded and observed every step from
   Python, the reward in numpy), where sumo and its Python client are installed (tools/install-deps.sh sumo;
   skipped with a message otherwise): the dynamics check of sumo_ring.py, then 1, 4, ... (--sumo-envs)
   environments stepped in turn with the action 0 for --sumo-steps steps, through traci (a socket to each sumo
   process) reading by single calls and by subscriptions, and through libsumo (SUMO inside this process, one
   simulation per process: one environment) where importable; best of --repeats, wall and CPU (this process and
   the sumo processes: /proc/<pid>/stat), and the ratio of VectorEnv on 1 thread to each.
OpenMP reads OMP_WAIT_POLICY when the process starts: run the script once per policy (bench/README.md).
Usage: PYTHONPATH=python WAVEFUEL_LIB=lib/libwavefuel.so /usr/bin/python3 bench/rl_envs/run.py
       [--envs 64] [--steps 2000] [--traj-steps 500] [--repeats 3] [--check-steps 600] [--sumo-envs 1,4,64 | 0]
       [--sumo-steps 500] [--load]"""
import argparse
import os
import platform
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))
from busy_load import start_load  # noqa: E402
import wavefuel as wf  # noqa: E402
from numpy_ring import NumpyRing  # noqa: E402
from ring_spec import ring_spec  # noqa: E402
import sumo_ring  # noqa: E402


def machine():
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")), "?")
    gcc = subprocess.run(["cc", "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    return (f"{cpu}, {os.cpu_count()} cores; Python {platform.python_version()}, numpy {np.__version__}; {gcc}; "
            f"load average {os.getloadavg()[0]:.2f} at the start")


def baseline_for(venv, noise_mps2, seed=0):
    """A NumpyRing with venv's rings, parameters and current state (read from wavefuel's loaded scenarios)."""
    p = ring_spec(venv.envs)
    base = NumpyRing(p["length_m"], p["av"], p["idm"], p["limits"], p["energy"], p["car_m"], p["dt_s"], noise_mps2,
                     p["reward"], p["action_range"], seed)
    st = [e.sim.state() for e in venv.envs]
    base.set_state([s["x_m"] for s in st], [s["v_mps"] for s in st])
    return base


def agreement(n_envs, steps):
    venv = wf.envs.VectorEnv(n_envs, noise_mps2=0.0, horizon_s=1e4, warmup_s=30.0, threads=2)
    obs_w, _ = venv.reset(seed=5)
    base = baseline_for(venv, 0.0)
    obs_b = base.observe()
    d_obs, d_x, d_v, d_r = np.max(np.abs(obs_w - obs_b)), 0.0, 0.0, 0.0
    for k in range(steps):
        # A gap-keeping command (collision-free: the baseline has no overlap repair), from wavefuel's observation.
        u = np.clip(0.5 * (obs_w[:, :, 1] - obs_w[:, :, 0]) + 0.2 * (obs_w[:, :, 2] - 8.0), -1.0, 1.0)
        obs_w, r_w, _, _, _ = venv.step(u)
        obs_b, r_b, _ = base.step(u)
        x_w = np.array([e.sim.state()["x_m"] for e in venv.envs])
        v_w = np.array([e.sim.state()["v_mps"] for e in venv.envs])
        d_x, d_v = max(d_x, np.max(np.abs(x_w - base.x))), max(d_v, np.max(np.abs(v_w - base.v)))
        d_r = max(d_r, np.max(np.abs(r_w - r_b) / np.abs(r_b)))
        d_obs = max(d_obs, np.max(np.abs(obs_w - obs_b)))
    venv.close()
    ok = d_x <= 1e-6 and d_v <= 1e-6 and d_r <= 1e-9
    print(f"agreement over {steps} steps of {n_envs} rings (no noise, gap-keeping commands): max |dx| {d_x:.3g} m, "
          f"max |dv| {d_v:.3g} m/s, max |d obs| {d_obs:.3g}, max relative |d reward| {d_r:.3g}: "
          f"{'OK' if ok else 'TOO FAR'}")
    return ok


def timed(step, steps):
    """(wall s, CPU s of the process: all its threads) of `steps` calls."""
    t, c = time.perf_counter(), time.process_time()
    for _ in range(steps):
        step()
    return np.array([time.perf_counter() - t, time.process_time() - c])


def bench_vector(n_envs, steps, repeats, baseline=False, **env_kw):
    """{case: (env-steps per wall second, per CPU second, reset of all environments s, median ratio)} for VectorEnv
    on 1 and 2 threads (and the numpy baseline of the same rings): each repeat times every case in turn, so that all
    meet the same load; the best wall and the best CPU time of the repeats, and (with the baseline) the median over
    the repeats of the baseline's wall time / the case's in the same repeat (on a VM whose speed changes from one
    minute to the next, the pairs' ratios are steadier than the best times)."""
    venvs, rows, cases = {}, {}, {}
    for threads, check in ((1, None), (2, None), (2, 0)):
        name = f"VectorEnv, {threads} thread{'s' if threads > 1 else ''}" + (", always" if check == 0 else "")
        venvs[name] = v = wf.envs.VectorEnv(n_envs, threads=threads, thread_check=check, **env_kw)
        t = time.perf_counter()
        v.reset(seed=1)
        rows[name] = time.perf_counter() - t
        cases[name] = lambda v=v, a=np.zeros((n_envs, v.n_av)): v.step(a)
    if baseline:
        base = baseline_for(venvs["VectorEnv, 1 thread"], 0.2)
        cases["numpy baseline"] = lambda a=np.zeros((n_envs, int(base.av.sum()))): base.step(a)
        rows["numpy baseline"] = float("nan")
    best = {k: np.array([np.inf, np.inf]) for k in cases}
    walls = {k: [] for k in cases}
    for _ in range(repeats):
        for k, f in cases.items():
            t = timed(f, steps)
            best[k] = np.minimum(best[k], t)
            walls[k].append(t[0])
    for v in venvs.values():
        v.close()
    ratio = {k: float(np.median(np.array(walls["numpy baseline"]) / np.array(walls[k]))) if baseline else float("nan")
             for k in cases}
    return {k: (n_envs * steps / best[k][0], n_envs * steps / best[k][1], rows[k], ratio[k]) for k in cases}


def bench_sumo(n_envs, counts, steps, repeats, vector_1thread):
    """The SUMO cases (item 4 of the docstring): prints their table; vector_1thread: VectorEnv's (env-steps per wall
    second, per CPU second) on 1 thread. Returns the BENCH lines' cases {name: (wall, cpu)}."""
    venv = wf.envs.VectorEnv(n_envs, horizon_s=1e4, threads=1)
    venv.reset(seed=1)  # the rings bench_vector timed (the same seed): their lengths
    spec = ring_spec(venv.envs)
    venv.close()
    ok = all([sumo_ring.check(c) for c in sumo_ring.clients()])
    rows = {}
    for client in sumo_ring.clients():
        for mode in sumo_ring.MODES:
            for n in (counts if client == "traci" else [1]):  # libsumo: one simulation per process
                print(f"  SUMO {client} {mode}, {n} environment(s), load {os.getloadavg()[0]:.2f}", flush=True)
                rows[(client, mode, n)] = sumo_ring.bench(spec, n, steps, repeats, client, mode)
    w1, c1 = vector_1thread
    print(f"\nSUMO rings of 22 vehicles ({n_envs} ring lengths, cm edges), {steps} steps of every environment, "
          f"action 0, best of {repeats}; VectorEnv on 1 thread: {w1:.3g} env-steps/s wall, {c1:.3g} per CPU-second:")
    print("| client, observation | environments | round trips per env-step | env-steps/s (wall) | µs per env-step "
          "(wall) | CPU µs per env-step: Python / sumo | VectorEnv 1 thread / this: wall, CPU | simulationStep alone: "
          "µs per env-step (wall; sumo CPU) | numpy reward, µs per env-step | reset of all, s | collisions |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for (client, mode, n), r in rows.items():
        wall, cpu = r["env_steps_per_s"], r["env_steps_per_cpu_s"]
        split = (f"{1e6 / cpu - r['sumo_cpu_us']:.0f} / {r['sumo_cpu_us']:.0f}" if client == "traci" else
                 f"{1e6 / cpu:.0f} (SUMO in process)")
        bare = f"{r['bare_us']:.0f}; " + (f"{r['bare_sumo_cpu_us']:.0f}" if client == "traci" else "in process")
        trips = r["calls_per_step"] if client == "traci" else f"0 ({r['calls_per_step']} calls in process)"
        print(f"| {client}, {mode} | {n} | {trips} | {wall:.3g} | {1e6 / wall:.0f} | {split} | "
              f"{w1 / wall:.0f}x, {c1 / cpu:.0f}x | {bare} | {r['reward_us']:.0f} | {r['reset_s']:.2f} | "
              f"{r['collisions']} |")
    best = max(rows, key=lambda k: rows[k]["env_steps_per_s"])
    traci = max((k for k in rows if k[0] == "traci"), key=lambda k: rows[k]["env_steps_per_s"])
    for label, k in (("fastest SUMO case", best), ("fastest traci case", traci)):
        ratio = w1 / rows[k]["env_steps_per_s"]
        print(f"VectorEnv 1 thread / {label} ({', '.join(map(str, k))} env): {ratio:.0f}x wall, "
              f"{c1 / rows[k]['env_steps_per_cpu_s']:.0f}x CPU: the issue's 100x "
              f"{'met' if ratio >= 100 else 'NOT met'}")
    out = {f"sumo {c} {m} {n}env": (r["env_steps_per_s"], r["env_steps_per_cpu_s"]) for (c, m, n), r in rows.items()}
    return out, ok


def stop_and_go(duration_s=600.0):
    """A synthetic stop-and-go trace (m/s): cruising at 25 m/s with waves down to 5 m/s every 90 s."""
    t = np.arange(0.0, duration_s + 0.5, 1.0)
    v = 15.0 + 10.0 * np.cos(2.0 * np.pi * t / 90.0)
    return t, v


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--envs", type=int, default=64)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--traj-steps", type=int, default=500)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--check-steps", type=int, default=600)
    ap.add_argument("--sumo-envs", default="1,4,64",
                    help="numbers of SUMO environments stepped in turn (each at least 1); 0: no SUMO cases")
    ap.add_argument("--sumo-steps", type=int, default=500)
    ap.add_argument("--load", action="store_true", help="two CPU-bound processes beside the timed cases")
    a = ap.parse_args()
    try:
        a.sumo_counts = [int(x) for x in a.sumo_envs.split(",")]
    except ValueError:
        a.sumo_counts = [-1]
    if a.sumo_counts != [0] and min(a.sumo_counts) < 1:
        ap.error(f"--sumo-envs: a comma-separated list of counts of at least 1, or 0 for none (got {a.sumo_envs!r})")
    print("machine:", machine())
    ok = agreement(4, a.check_steps)
    load = start_load(600.0) if a.load else []
    try:
        return timed_cases(a, ok)
    finally:
        for p in load:
            p.kill()
            p.wait()


def timed_cases(a, ok):
    if a.load:
        print("beside two CPU-bound processes (--load)")
    rings = bench_vector(a.envs, a.steps, a.repeats, baseline=True, horizon_s=1e4)
    base = rings["numpy baseline"]
    print(f"\n{a.envs} rings of 22 vehicles, {a.steps} steps, best of {a.repeats} (and the median of the repeats' "
          f"ratios):")
    print("| | env-steps/s (wall) | vs numpy | vs numpy, median of the repeats | env-steps per CPU-second | vs numpy "
          "| reset of all environments, s |")
    print("|---|---|---|---|---|---|---|")
    for k, (wall, cpu, reset_s, ratio) in rings.items():
        print(f"| {k} | {wall:.3g} | {wall / base[0]:.2f}x | {ratio:.2f}x | {cpu:.3g} | {cpu / base[1]:.2f}x "
              f"| {reset_s:.2f} |")
    traj = bench_vector(a.envs, a.traj_steps, a.repeats, env=wf.envs.TrajectoryEnv, trace=stop_and_go(),
                        n_vehicles=200, humans_per_av=4)
    print(f"\n{a.envs} trajectory environments of 200 vehicles, {a.traj_steps} steps, best of {a.repeats}:")
    print("| | env-steps/s (wall) | vehicle-steps/s (wall) | env-steps per CPU-second | reset of all environments, s |")
    print("|---|---|---|---|---|")
    for k, (wall, cpu, reset_s, _) in traj.items():
        print(f"| {k} | {wall:.3g} | {wall * 200:.3g} | {cpu:.3g} | {reset_s:.1f} |")
    cases = [(k, (wall, cpu)) for k, (wall, cpu, _, _) in
             list(rings.items()) + [(f"traj {k}", v) for k, v in traj.items()]]
    why = "--sumo-envs 0" if a.sumo_counts == [0] else sumo_ring.available()
    if why:
        print(f"\nSUMO + TraCI: not run: {why}")
    else:
        sumo, sumo_ok = bench_sumo(a.envs, a.sumo_counts, a.sumo_steps, a.repeats,
                                   rings["VectorEnv, 1 thread"][:2])
        cases += list(sumo.items())
        ok = ok and sumo_ok
    for k, (wall, cpu) in cases:
        print(f"BENCH rl_envs case={k.replace(' ', '_').replace(',', '')} env_steps_per_s={wall:.6g} "
              f"env_steps_per_cpu_s={cpu:.6g} omp_wait_policy={os.environ.get('OMP_WAIT_POLICY', 'default')} "
              f"load={int(a.load)}")
    print(f"load average {os.getloadavg()[0]:.2f} at the end")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
