"""The training and evaluation setting of examples/rl/ (README.md): speed traces, the platoon environment
(wavefuel.envs.TrajectoryEnv), its per-AV reward, and rollouts with the platoon's fuel counted step by step.

The platoon: N_VEHICLES midsize sedans behind a virtual leader replaying a trace, an automated vehicle (AV) after
every HUMANS_PER_AV IDM humans (interleaved: road indices 2, 7, 12, 17 of 20), humans with acceleration noise
NOISE_MPS2. "The platoon's fuel" is the fuel of the AVs and of the humans behind them: the vehicles from the first
AV back (18 of 20); the two humans ahead of it see no AV. No torch here: evaluate.py and run_c.py use it too."""
import os

import numpy as np

import wavefuel
from wavefuel.envs import TrajectoryEnv

from stop_and_go import stop_and_go

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
N_VEHICLES, HUMANS_PER_AV, NOISE_MPS2, VEHICLE_CLASS = 20, 4, 0.2, "midsize_sedan"
DT_S, ACTION_EVERY = 0.1, 5  # a decision every 0.5 s
ACCEL_RANGE_MPS2 = (-3.0, 3.0)  # the environment's action space; the exported network clips to it too
AV = TrajectoryEnv.AV

# Traces: a drive cycle by name (DATA/cycles/NAME.csv), or stop_and_go:SEED (stop_and_go.py).
TRAIN_TRACES = ("udds", "hwfet", "hhddt_transient", "stop_and_go:1")
HELDOUT_TRACES = ("wltc3", "us06", "hhddt_cruise", "stop_and_go:2")


def default_data_dir():
    """$WAVEFUEL_DATA, else ../shared/data next to the repository (where wavefuel itself looks: docs/cycles.md)."""
    return os.environ.get("WAVEFUEL_DATA") or os.path.join(os.path.dirname(REPO), "shared", "data")


def load_trace(spec, data_dir):
    """(time_s, speed_mps) of a trace spec: a drive cycle's CSV (time_s,speed_mps, 1 Hz, m/s:
    DATA/cycles/README.md) or stop_and_go:SEED."""
    if spec.startswith("stop_and_go:"):
        return stop_and_go(int(spec.split(":", 1)[1]))
    path = os.path.join(data_dir, "cycles", spec + ".csv")
    if not os.path.exists(path):
        raise SystemExit(f"{path}: no such drive cycle (give the data directory with --data; README.md)")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return data[:, 0], data[:, 1]


class PlatoonEnv(TrajectoryEnv):
    """TrajectoryEnv with this example's platoon; humans_only: the AV group drives as the humans (IDM with the same
    noise): the all-human baseline on the same scenario and seed."""

    def __init__(self, trace, humans_only=False, **kw):
        kw = dict(dict(n_vehicles=N_VEHICLES, humans_per_av=HUMANS_PER_AV, dt_s=DT_S, action_every=ACTION_EVERY,
                       noise_mps2=NOISE_MPS2, vehicle_class=VEHICLE_CLASS, accel_range_mps2=ACCEL_RANGE_MPS2,
                       threads=1), **kw)
        super().__init__(trace, **kw)
        self.humans_only = humans_only

    def _scenario(self):
        d = super()._scenario()
        if self.humans_only:
            for g in d["fleet"]["drivers"]:
                if g["name"] == self.AV:
                    g["model"], g["noise_mps2"] = "idm", self.noise_mps2
        return d



def acc_law(obs, k_gap=0.4, k_dv=0.8, T=1.1, s0=2.0, v0=30.0, k_v=0.4):
    """The `acc` model's acceleration (src/models/cf/acc.c, its default parameters) for rows [v, v_lead, gap]:
    min(k_gap (gap - s0 - T v) + k_dv (v_lead - v), k_v (v0 - v)); the law an external group follows without
    commands, and the target of the policy's initialisation (train.py)."""
    v, vl, gap = obs[:, 0], obs[:, 1], obs[:, 2]
    return np.minimum(k_gap * (gap - s0 - T * v) + k_dv * (vl - v), k_v * (v0 - v))


class Reward:
    """The per-AV reward of train.py, computed here from the run's state (the same terms as issue 17's reward:
    fuel, gap bounds, comfort). AV j's segment: itself and the humans behind it up to the next AV; the segments
    partition the platoon (the AVs' fuel terms weighted by their segments' sizes add up to the platoon's). Per
    decision of dt = DT_S x ACTION_EVERY s:
      fuel    = -mean over the segment of each vehicle's fuel rate (g/s), its class model at its speed at the
                decision's start and the acceleration (v_end - v_start) / dt that took it to its speed at the end,
                net of the distance it covered, (v_start + v_end) / 2 x dt, at FUEL_PER_M g/m (8 L/100km of
                gasoline): a discounted fuel rate alone pays for lagging behind (less distance now, the fuel to catch
                up later and discounted), which the distance's worth in fuel cancels;
      gap     = -W_GAP_LOW (gap_min - gap)^2 below gap_min = 2 m + 0.6 s x v, -W_GAP_HIGH (gap - gap_max)^2 above
                gap_max = 20 m + 2.5 s x v (the AV's gap and speed at the decision's end, m);
      comfort = -W_ACCEL a^2 - W_JERK j^2, a the AV's acceleration as above, j its change from the previous
                decision over dt."""
    W_GAP_LOW, W_GAP_HIGH, W_ACCEL, W_JERK = 0.05, 0.01, 0.02, 0.001
    FUEL_PER_M = 0.06  # g/m: 8 L/100km at 750 g/L

    def __init__(self, n_vehicles, av_index):
        self.cls = wavefuel.VehicleClass(VEHICLE_CLASS)
        ends = list(av_index[1:]) + [n_vehicles]
        self.seg = np.zeros(n_vehicles, np.int64) - 1
        for j, (a, b) in enumerate(zip(av_index, ends)):
            self.seg[a:b] = j
        self.av_index, self.n_av = np.asarray(av_index), len(av_index)
        self.count = np.bincount(self.seg[self.seg >= 0], minlength=self.n_av)
        self.prev_a = None

    def __call__(self, v0, v1, gap1, dt):
        a = (v1 - v0) / dt
        f = self.cls.fuel(v0, a, 0.0) - self.FUEL_PER_M * (v0 + v1) / 2
        m = self.seg >= 0
        fuel = -np.bincount(self.seg[m], weights=f[m], minlength=self.n_av) / self.count
        v_av, g_av, a_av = v1[self.av_index], gap1, a[self.av_index]
        low, high = 2.0 + 0.6 * v_av, 20.0 + 2.5 * v_av
        gap = -(self.W_GAP_LOW * np.maximum(low - g_av, 0) ** 2 + self.W_GAP_HIGH * np.maximum(g_av - high, 0) ** 2)
        jerk = np.zeros(self.n_av) if self.prev_a is None else (a_av - self.prev_a) / dt
        self.prev_a = a_av
        comfort = -(self.W_ACCEL * a_av ** 2 + self.W_JERK * jerk ** 2)
        return fuel + gap + comfort, {"fuel": fuel, "gap": gap, "comfort": comfort}


def windows(trace, length_s, rng, count):
    """`count` windows of length_s seconds of a trace (t, v) starting at random whole seconds (the whole trace when
    shorter), as (t, v) arrays with t from 0."""
    t, v = trace
    out = []
    for _ in range(count):
        if t[-1] <= length_s:
            out.append((t, v))
            continue
        start = int(rng.integers(0, int(t[-1] - length_s) + 1))
        m = (t >= t[start]) & (t <= t[start] + length_s)
        out.append((t[m] - t[start], v[m]))
    return out


class Episode:
    """One episode of a PlatoonEnv, its run driven here rather than by env.step: the run of the scenario that
    env.reset(seed) would build (env._scenario() drawn from default_rng(seed)), the platoon's fill stepped as
    env.reset steps it, then decisions every ACTION_EVERY steps with the AVs' commands from `controller(obs) ->
    accelerations` (None: no command, the AVs drive as acc) and, with count_fuel, the platoon's fuel integrated at
    every step as the engine integrates it (fuel_rate_gps x dt). Only the environment's scenario is used: the
    all-human variant's AV group (idm) takes no commands and has no observe()."""

    def __init__(self, env, seed):
        self.env = env
        env.np_random = np.random.default_rng(seed)
        self.sim = wavefuel.Simulation(wavefuel.Scenario.from_dict(env._scenario()), threads=env.threads)
        self.sim.step(int(round(env._fill_s() / env.dt_s)))
        self.t0 = self.sim.t
        st = self._state(check=False)
        self.n = st["v_mps"].size
        if self.n != env.n_vehicles:
            raise RuntimeError(f"{self.n} of {env.n_vehicles} vehicles entered during the fill")
        self.av_group = self.sim.group_index(AV)
        self.av_index = np.flatnonzero(st["group_id"] == self.av_group)
        self.platoon = np.arange(self.n) >= self.av_index[0]
        self.x0 = np.array(st["x_m"])
        self.fuel_g = np.zeros(self.n)
        self.reward = Reward(self.n, self.av_index)
        self.obs = self._observe()
        self.done = False

    def _observe(self):
        if not self.env.humans_only:
            return self.sim.observe(AV)
        # An idm group has no observe(): its rows from the state (gaps and leader speeds of the last step).
        st = self.sim.state()
        m = st["group_id"] == self.av_group
        return np.column_stack([st["v_mps"][m], st["v_lead_mps"][m], st["gap_m"][m]])

    def close(self):
        self.sim.close()

    def _state(self, check=True):
        st = self.sim.state()
        if check and st["v_mps"].size != self.n:
            raise RuntimeError(f"{st['v_mps'].size} vehicles on the road, expected {self.n}")
        return st

    def step(self, action, count_fuel=False, record=None):
        """One decision: returns (obs, reward per AV, terms); sets self.done at the horizon. With count_fuel and a
        list `record`, appends (time since the episode's start s, speeds m/s in road order, platoon fuel so far g)
        at every step."""
        sim, k = self.sim, self.env.action_every
        v0 = np.array(self._state()["v_mps"])
        if action is not None and not self.env.humans_only:
            sim.set_actions(AV, np.clip(action, *ACCEL_RANGE_MPS2))
        if count_fuel:
            for _ in range(k):
                sim.step(1)
                st = self._state()
                self.fuel_g += st["fuel_rate_gps"] * self.env.dt_s
                if record is not None:
                    record.append((sim.t - self.t0, np.array(st["v_mps"]),
                                   float(self.fuel_g[self.platoon].sum())))
        else:
            sim.step(k)
            st = self._state()
        v1 = np.array(st["v_mps"])
        self.obs = self._observe()
        r, terms = self.reward(v0, v1, self.obs[:, 2], self.env.dt_s * k)
        self.done = sim.t - self.t0 >= self.env.horizon_s - 1e-9
        return self.obs, r, terms

    def platoon_totals(self):
        """(fuel g, distance m) of the platoon since the episode's start."""
        x = np.array(self._state()["x_m"])
        return float(self.fuel_g[self.platoon].sum()), float((x - self.x0)[self.platoon].sum())


def l_per_100km(fuel_g, dist_m):
    dens = wavefuel.VehicleClass(VEHICLE_CLASS).keys["fuel_density_g_per_l"][0]
    return fuel_g / dens / (dist_m / 1e5)
