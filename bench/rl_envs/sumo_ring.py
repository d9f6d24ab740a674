#!/usr/bin/python3
"""The ring environment of bench/rl_envs driven through SUMO, for the issue 17 comparison "a SUMO + TraCI loop of the
same ring": one SUMO simulation per environment, commanded and observed every step from Python, as Flow (Wu et
al.) drives SUMO for reinforcement learning.

The ring (RingEnv's parameters, read from a RingEnv by ring_spec.py): 22 vehicles of the class's length on one lane
of length L (drawn in RingEnv's [220, 270] m). As bench/vs_sumo builds its rings: a regular polygon of straight
edges (here one per 2 vehicles: 11 edges of L/11, in whole cm: sumo_length) with their lengths set, netconvert
without internal links, so the lap is exactly their sum; every vehicle's route is one lap from its start edge repeated for more laps than the run drives.
Humans: SUMO's IDM with RingEnv's parameters (v0 = maxSpeed with speedFactor 1 on lanes of 40 m/s, T = tau, s0 =
minGap, a = accel, b = decel, delta 4, decel_max = emergencyDecel), sigma 0; the ballistic update
(--step-method.ballistic), dt 0.1 s, no teleports (--time-to-teleport -1), collisions only warned about (a collision
would otherwise remove a vehicle; none happen in the runs below). reset() starts SUMO (every vehicle at rest, evenly
spaced) and drives warmup_s in one simulationStep call (the automated vehicle drives SUMO's IDM meanwhile), then
subscribes as below.

The automated vehicle's command: every step setSpeed(av, max(v + a dt, 0)) with speed mode 0, a the action clipped
to the action space and to the group's limits (as wavefuel's external group applies its limits). Speed mode 0 turns
off SUMO's safe-speed, maximum-acceleration and maximum-deceleration overrides, so the vehicle drives exactly the
commanded acceleration over the next step (ballistic: x += (v + v') dt / 2), as wavefuel's external group does;
with the default speed mode SUMO would silently replace a command above its own safe speed, another environment.
setAcceleration(id, a, duration) holds an acceleration for a duration, after which SUMO's model takes over again:
one setSpeed a step is the same command with the plainest meaning (Flow sends slowDown(id, v + a dt, 1e-3): the
same).

Observation, reward: own speed, leader speed and gap (getLeader's distance + the vehicle's minGap: SUMO measures it
from front bumper + minGap to the leader's back) and every vehicle's speed for the reward (every vehicle of a ring is
in the fuel's scope), read in one of two ways:
- "calls": after simulationStep, getSpeed of each of the 22 vehicles and getLeader of the automated one: with the
  setSpeed and the simulationStep, 25 TraCI round trips a step (CALLS_PER_STEP);
- "subscriptions": each vehicle subscribed to its speed, the automated one to its leader: the values come back in
  simulationStep's answer, 2 round trips a step (setSpeed, simulationStep); Flow's TraCI kernel subscribes too.
The reward is numpy_ring.py's (the CIRCLES model and wavefuel.envs.Reward's terms, computed in numpy): the same
code the numpy baseline runs.

SUMO's Python clients: traci (a TCP socket to a sumo process, any number of them) and libsumo (SUMO in this
process: one simulation per process, so one environment), from the Debian packages sumo / sumo-tools
(tools/install-deps.sh sumo) or $SUMO_HOME/tools. Differences from wavefuel's RingEnv, none of which costs SUMO
time: humans without acceleration noise (SUMO's IDM has none: its sigma is ignored, shown by `--check`), a start
at rest instead of at equilibrium (reset drives warmup_s from rest), ring lengths rounded to whole cm per edge.

`--check` compares the dynamics with wavefuel's (check()): a 230.01 m ring from rest, vehicle 0 3 m ahead of its
even place, no noise, the automated vehicle commanded through setSpeed with the IDM formula of its observation (so
that every vehicle should drive IDM), against wavefuel's ring of 22 IDM drivers: every vehicle's speed and the
automated vehicle's gap at every step for 60 s (within 1e-9), the mean speed every 10 s printed; and shows that
SUMO's IDM ignores sigma (sigma_effect()).
Usage: PYTHONPATH=python WAVEFUEL_LIB=lib/libwavefuel.so /usr/bin/python3 bench/rl_envs/sumo_ring.py --check"""
import argparse
import contextlib
import importlib
import io
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

from numpy_ring import circles_fuel, idm_accel, reward_terms

SUMO_HOME = os.environ.get("SUMO_HOME", "/usr/share/sumo")
VAR_SPEED, VAR_LEADER = 0x40, 0x68  # TraCI's variable ids (traci.constants)
MODES = ("calls", "subscriptions")
CALLS_PER_STEP = {"calls": lambda n: n + 3, "subscriptions": lambda n: 2}  # round trips per env-step, n vehicles
VEH_PER_EDGE = 2


def clients():
    """{name: module} of SUMO's Python clients importable here, of "traci" and "libsumo". $SUMO_HOME/tools goes at
    the end of sys.path: Debian's compiled libsumo is in dist-packages, tools/libsumo is its source without it."""
    tools = os.path.join(SUMO_HOME, "tools")
    if os.path.isdir(tools) and tools not in sys.path:
        sys.path.append(tools)
    found = {}
    for name in ("traci", "libsumo"):
        try:
            found[name] = importlib.import_module(name)
        except ImportError:
            pass
    return found


def available():
    """Why the SUMO ring cannot run here (a message), or None when it can."""
    if not (shutil.which("sumo") and shutil.which("netconvert")):
        return "sumo / netconvert not on PATH (Debian: tools/install-deps.sh sumo)"
    if "traci" not in clients():
        return f"the traci Python module is not importable (Debian package sumo, or $SUMO_HOME/tools: {SUMO_HOME})"
    return None


def sumo_length(length_m, n):
    """The lap of SUMO's ring of n vehicles nearest to length_m: netconvert writes lengths in cm (its default
    --precision 2), so the edges' lengths are whole cm and the lap a multiple of their number of cm."""
    k = n // VEH_PER_EDGE
    if k * VEH_PER_EDGE != n or k < 3:
        raise ValueError(f"{n} vehicles: the SUMO ring needs a multiple of {VEH_PER_EDGE}, at least {3 * VEH_PER_EDGE}")
    return k * round(length_m / k, 2)  # edge_m = this / k gives back the cm


def write_ring(d, length_m, n, spec, laps, perturb_m=0.0, sigma=0.0):
    """The network and routes of the ring of lap sumo_length(length_m, n) in directory d: n vehicles at rest,
    evenly spaced (vehicle 0 moved perturb_m forward), vehicle 0 the automated one (type "av"), the others
    "human"; sigma: SUMO's driver imperfection (its IDM ignores it: sigma_effect)."""
    k = n // VEH_PER_EDGE
    edge_m = sumo_length(length_m, n) / k
    spacing_m = edge_m / VEH_PER_EDGE
    if spacing_m / 2 < spec["car_m"]:
        raise ValueError(f"ring of {length_m} m: {n} vehicles of {spec['car_m']} m do not fit whole on their edges")
    r = length_m / (2 * math.pi)  # node positions only draw the polygon; each edge's length is set explicitly
    with open(os.path.join(d, "ring.nod.xml"), "w") as f:
        f.write("<nodes>\n" + "".join(f'  <node id="n{j}" x="{r * math.cos(2 * math.pi * j / k):.3f}" '
                                      f'y="{r * math.sin(2 * math.pi * j / k):.3f}" type="priority"/>\n'
                                      for j in range(k)) + "</nodes>\n")
    with open(os.path.join(d, "ring.edg.xml"), "w") as f:
        f.write("<edges>\n" + "".join(f'  <edge id="e{j}" from="n{j}" to="n{(j + 1) % k}" numLanes="1" speed="40" '
                                      f'length="{edge_m!r}"/>\n' for j in range(k)) + "</edges>\n")
    subprocess.run(["netconvert", "--xml-validation", "never", "-n", "ring.nod.xml", "-e", "ring.edg.xml", "-o",
                    "ring.net.xml", "--no-internal-links", "--no-turnarounds"], cwd=d, check=True, capture_output=True)
    v0, T, s0, a, b = spec["idm"]
    (_, hdec), (_, adec) = spec["limits"]
    with open(os.path.join(d, "ring.rou.xml"), "w") as f:
        f.write("<routes>\n")
        for name, dec in (("human", hdec), ("av", adec)):
            f.write(f'  <vType id="{name}" carFollowModel="IDM" accel="{a!r}" decel="{b!r}" emergencyDecel="{dec!r}" '
                    f'sigma="{sigma!r}" tau="{T!r}" minGap="{s0!r}" length="{spec["car_m"]!r}" maxSpeed="{v0!r}" delta="4" '
                    'speedFactor="1" speedDev="0"/>\n')
        for j in range(k):
            edges = " ".join(f"e{(j + m) % k}" for m in range(k))
            f.write(f'  <route id="r{j}" edges="{edges}" repeat="{laps}"/>\n')
        # Vehicle i's front bumper at (i + 1/2) spacing; within an edge the front one first (SUMO inserts each new
        # vehicle at the start of its lane's list).
        for i in sorted(range(n), key=lambda i: (i // VEH_PER_EDGE, -i)):
            f.write(f'  <vehicle id="v{i}" type="{"av" if i == 0 else "human"}" route="r{i // VEH_PER_EDGE}" '
                    f'depart="0" departPos="{(i % VEH_PER_EDGE + 0.5) * spacing_m + (i == 0) * perturb_m!r}" '
                    'departSpeed="0" departLane="0"/>\n')
        f.write("</routes>\n")


def proc_cpu_s(pid):
    """CPU seconds process pid has run so far, all its threads: the first field of /proc/<pid>/schedstat, in ns
    (/proc/<pid>/stat's utime and stime count 10 ms ticks: too coarse for a 40 ms loop)."""
    with open(f"/proc/{pid}/schedstat") as f:
        return int(f.read().split()[0]) * 1e-9


class SumoRing:
    """One ring environment in its own SUMO simulation. spec: ring_spec.ring_spec()'s dict; length_m: this ring's
    length (made sumo_length's); client: "traci" or "libsumo"; mode: one of MODES; horizon_s: how long the run may
    be stepped after the warm-up (the routes' laps); perturb_m: vehicle 0 starts this far ahead of its even place;
    sigma: write_ring's.
    step(action) -> (obs (1, 3), reward, terms) as numpy_ring.NumpyRing.step for B = 1. Owns a temporary directory
    and the SUMO simulation until close()."""

    _labels = 0

    def __init__(self, spec, length_m, client="traci", mode="subscriptions", n_vehicles=22, warmup_s=60.0,
                 horizon_s=1000.0, perturb_m=0.0, sigma=0.0):
        if mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)} (got {mode!r})")
        self.spec, self.client, self.mode, self.n = spec, client, mode, n_vehicles
        self.L = sumo_length(length_m, n_vehicles)
        self.dt, self.warmup_s = spec["dt_s"], warmup_s
        self.lo, self.hi = spec["action_range"]
        self.amax, self.dmax = spec["limits"][1]
        self.s0 = spec["idm"][2]
        self.ids = [f"v{i}" for i in range(n_vehicles)]
        self.dir = tempfile.mkdtemp(prefix="wf_sumo_ring_")
        laps = math.ceil(spec["idm"][0] * (warmup_s + horizon_s) / self.L) + 2
        write_ring(self.dir, self.L, n_vehicles, spec, laps, perturb_m, sigma)
        self.mod = clients()[client]
        self.sim = self.pid = None
        SumoRing._labels += 1
        self.label = f"ring{SumoRing._labels}"

    def _cmd(self):
        return ["sumo", "--xml-validation", "never", "-n", os.path.join(self.dir, "ring.net.xml"), "-r",
                os.path.join(self.dir, "ring.rou.xml"), "--step-length", f"{self.dt!r}", "--step-method.ballistic",
                "true", "--time-to-teleport", "-1", "--collision.action", "warn", "--no-step-log", "--no-warnings",
                "--collision-output", os.path.join(self.dir, "collisions.xml"), "--seed", "1"]

    def reset(self):
        """Start SUMO, drive the warm-up; returns the first observation."""
        self.close_sim()
        if self.client == "traci":
            with contextlib.redirect_stdout(io.StringIO()):  # traci prints "Retrying" while sumo starts
                self.mod.start(self._cmd(), label=self.label, stdout=subprocess.DEVNULL)
            self.sim = self.mod.getConnection(self.label)
            self.pid = self.sim._process.pid
        else:
            self.mod.start(self._cmd())
            self.sim, self.pid = self.mod, os.getpid()
        self.sim.simulationStep(self.warmup_s)  # one call: SUMO runs to t = warmup_s
        got = self.sim.vehicle.getIDCount()
        if got != self.n:
            raise RuntimeError(f"SUMO ring of {self.L} m: {got} of {self.n} vehicles on the road after the warm-up")
        veh = self.sim.vehicle
        veh.setSpeedMode(self.ids[0], 0)
        if self.mode == "subscriptions":
            for vid in self.ids:
                veh.subscribe(vid, [VAR_SPEED])
            veh.subscribeLeader(self.ids[0], self.L)
        self.v = np.array([veh.getSpeed(vid) for vid in self.ids])
        self.a_prev = np.full((1, 1), np.nan)
        lead, gap = veh.getLeader(self.ids[0], self.L)
        self.obs = np.array([[self.v[0], self.v[self.ids.index(lead)], gap + self.s0]])
        return self.obs

    def _read(self):
        """Every vehicle's speed (in self.ids' order), the automated vehicle's leader id and TraCI gap."""
        veh = self.sim.vehicle
        if self.mode == "calls":
            v = np.array([veh.getSpeed(vid) for vid in self.ids])
            lead, gap = veh.getLeader(self.ids[0], self.L)
        else:
            res = veh.getAllSubscriptionResults()
            v = np.array([res[vid][VAR_SPEED] for vid in self.ids])
            lead, gap = res[self.ids[0]][VAR_LEADER]
        return v, lead, gap

    def step(self, action):
        a = min(max(min(max(float(action), self.lo), self.hi), -self.dmax), self.amax)
        self.sim.vehicle.setSpeed(self.ids[0], max(self.v[0] + a * self.dt, 0.0))
        self.sim.simulationStep()
        v_start, dt = self.v, self.dt
        self.v, lead, gap = self._read()
        self.obs = np.array([[self.v[0], self.v[int(lead[1:])], gap + self.s0]])
        acc = (self.v - v_start) / dt
        terms, self.a_prev = reward_terms(self.spec["reward"], circles_fuel(self.spec["energy"], v_start, acc)
                                          .mean(keepdims=True), self.obs[None, :, 2], acc[None, :1], self.a_prev, dt)
        return self.obs, terms["fuel"][0] + terms["gap"][0] + terms["comfort"][0], terms

    def cpu_s(self):
        """CPU seconds of the sumo process so far (traci; for libsumo SUMO is this process: 0, counted there)."""
        return proc_cpu_s(self.pid) if self.client == "traci" and self.sim is not None else 0.0

    def collisions(self):
        """Collisions SUMO recorded in the simulation closed last (its --collision-output)."""
        path = os.path.join(self.dir, "collisions.xml")
        with open(path) as f:
            return f.read().count("<collision ")

    def close_sim(self):
        if self.sim is not None:
            self.sim.close()
            self.sim = None

    def close(self):
        self.close_sim()
        shutil.rmtree(self.dir, ignore_errors=True)


def timed(envs, steps, step=None):
    """(wall s, CPU s of this process and of the sumo processes, CPU s of the sumo processes alone) of `steps`
    rounds of step(env) on every environment in turn (default: the action 0 m/s^2). With libsumo SUMO runs in this
    process: its CPU is in the second figure, the third is 0."""
    step = step or (lambda e: e.step(0.0))
    c_sumo = sum(e.cpu_s() for e in envs)
    t, c = time.perf_counter(), time.process_time()
    for _ in range(steps):
        for e in envs:
            step(e)
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    sumo = sum(e.cpu_s() for e in envs) - c_sumo
    return np.array([wall, cpu + sumo, sumo])


def bench(spec, n_envs, steps, repeats, client="traci", mode="subscriptions"):
    """{env_steps_per_s, env_steps_per_cpu_s, reset_s, collisions, ... (µs per env-step)} of n_envs SUMO rings
    (the lengths of spec["length_m"] in turn) stepped in turn with the action 0, best of repeats (back to back on
    the same rings, each continuing the last); also the same rings' SUMO steps alone (simulationStep, nothing set
    or read: the floor of any TraCI loop) and the reward's numpy (the floor of this one's Python side)."""
    envs = [SumoRing(spec, spec["length_m"][i % len(spec["length_m"])], client, mode,
                     horizon_s=(2 * repeats + 1) * steps * spec["dt_s"]) for i in range(n_envs)]
    try:
        t = time.perf_counter()
        for e in envs:
            e.reset()
        reset_s = time.perf_counter() - t
        best, bare = np.full(3, np.inf), np.full(3, np.inf)
        for _ in range(repeats):
            best = np.minimum(best, timed(envs, steps))
            bare = np.minimum(bare, timed(envs, steps, lambda e: e.sim.simulationStep()))
        e = envs[0]
        v = e.v + 0.1
        reward_s = min(timed([e], steps, lambda _: reward_terms(
            e.spec["reward"], circles_fuel(e.spec["energy"], e.v, (v - e.v) / e.dt).mean(keepdims=True),
            e.obs[None, :, 2], np.zeros((1, 1)), e.a_prev, e.dt))[0] for _ in range(repeats))
        for e in envs:
            e.close_sim()
        collisions = sum(e.collisions() for e in envs)
    finally:
        for e in envs:
            e.close()
    n = n_envs * steps
    return dict(env_steps_per_s=n / best[0], env_steps_per_cpu_s=n / best[1], reset_s=reset_s,
                collisions=collisions, calls_per_step=CALLS_PER_STEP[mode](envs[0].n),
                sumo_cpu_us=1e6 * best[2] / n, bare_us=1e6 * bare[0] / n, bare_cpu_us=1e6 * bare[1] / n,
                bare_sumo_cpu_us=1e6 * bare[2] / n, reward_us=1e6 * reward_s / steps)


def sigma_effect(client, spec, length_m=230.0, seconds=30.0, sigma=0.5):
    """Largest speed difference (m/s) over every vehicle and step between SUMO rings with sigma 0 and `sigma`,
    from rest with vehicle 0 3 m ahead, every vehicle driving SUMO's IDM: 0 when SUMO's IDM has no noise."""
    runs = []
    for sg in (0.0, sigma):  # one after the other: libsumo holds one simulation at a time
        ring = SumoRing(spec, length_m, client, "calls", warmup_s=0.1, horizon_s=seconds, perturb_m=3.0, sigma=sg)
        ring.reset()
        v = []
        for _ in range(int(round(seconds / spec["dt_s"]))):
            ring.sim.simulationStep()
            v.append([ring.sim.vehicle.getSpeed(vid) for vid in ring.ids])
        ring.close()
        runs.append(np.array(v))
    return float(np.max(np.abs(runs[0] - runs[1])))


def check(client, seconds=60.0, length_m=230.0, perturb_m=3.0, tol=1e-9):
    """The dynamics check of the module's docstring; True when every speed (m/s) and the automated vehicle's gap (m)
    agree with wavefuel's within tol at every step."""
    import wavefuel as wf
    from ring_spec import ring_spec
    env = wf.envs.RingEnv(noise_mps2=0.0)
    env.reset(seed=1)
    spec = ring_spec([env])
    length_m = sumo_length(length_m, env.n_vehicles)
    sc = dict(env.scenario_dict, road={"length_m": length_m}, initial={
        "state": "rest", "perturbation": {"vehicle": 0, "dx_m": perturb_m}})
    sc["fleet"] = dict(sc["fleet"], drivers=[{"name": "human", "model": "idm", "count": env.n_vehicles,
                                              "noise_mps2": 0.0}])
    env.close()
    sim = wf.Simulation(wf.Scenario.from_dict(sc), threads=1)
    ring = SumoRing(spec, length_m, client, "calls", env.n_vehicles, warmup_s=1.0, horizon_s=seconds,
                    perturb_m=perturb_m)
    obs = ring.reset()
    # SUMO inserts the vehicles departing at t = 0 during its step from 0 to dt: its state at time t is wavefuel's
    # at t - dt.
    warm = int(round(1.0 / spec["dt_s"])) - 1
    sim.step(warm)
    n = int(round(seconds / spec["dt_s"])) - warm
    d_v = d_gap = 0.0
    rows = []
    for k in range(n + 1):
        st = sim.state()
        x, v = np.asarray(st["x_m"]), np.asarray(st["v_mps"])
        gap = (x[1] - x[0]) % length_m - spec["car_m"]
        d_v, d_gap = max(d_v, float(np.max(np.abs(ring.v - v)))), max(d_gap, abs(obs[0, 2] - gap))
        if abs(sim.t / 10.0 - round(sim.t / 10.0)) < 1e-9 and sim.t > 0:
            rows.append((sim.t, ring.sim.simulation.getTime(), ring.v.mean(), v.mean(), obs[0, 0], v[0]))
        if k < n:
            obs, _, _ = ring.step(idm_accel(spec["idm"], obs[0, 0], obs[0, 1], obs[0, 2]))
            sim.step(1)
    ring.close_sim()
    collisions = ring.collisions()
    ring.close()
    sim.close()
    print(f"dynamics check ({client}): ring of {length_m:g} m, {env.n_vehicles} IDM drivers from rest, vehicle 0 "
          f"{perturb_m:g} m ahead, no noise; SUMO's vehicle 0 commanded through setSpeed with the IDM of its "
          f"observation from t = 1 s; {collisions} collisions")
    print("SUMO inserts the vehicles in its first step: its time t is wavefuel's t - dt.")
    print("| t (s) wavefuel / SUMO | mean speed SUMO | mean speed wavefuel | vehicle 0 SUMO | vehicle 0 wavefuel |")
    print("|---|---|---|---|---|")
    for t, ts, ms, mw, v0s, v0w in rows:
        print(f"| {t:g} / {ts:g} | {ms:.9f} | {mw:.9f} | {v0s:.9f} | {v0w:.9f} |")
    ok = d_v <= tol and d_gap <= tol and collisions == 0
    print(f"max |dv| over every vehicle and step {d_v:.3g} m/s, max |d gap| of vehicle 0 {d_gap:.3g} m: "
          f"{'OK' if ok else 'TOO FAR'} (tolerance {tol:g})")
    d_sigma = sigma_effect(client, spec)
    print(f"SUMO's IDM with sigma 0.5 against sigma 0 (every vehicle IDM, 30 s): max |dv| {d_sigma:.3g} m/s: "
          f"{'no noise in SUMO: its humans drive without RingEnv noise' if d_sigma == 0 else 'sigma acts'}")
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="compare the dynamics with wavefuel's (the default)")
    ap.add_argument("--seconds", type=float, default=60.0)
    a = ap.parse_args()
    why = available()
    if why:
        print(f"SUMO ring: not run: {why}")
        return 0
    return 0 if all([check(c, a.seconds) for c in clients()]) else 1


if __name__ == "__main__":
    sys.exit(main())
