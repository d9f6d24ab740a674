"""Reinforcement-learning environments with the Gymnasium API, on wavefuel runs whose automated vehicles are a
driver group of model `external` (docs/controllers.md): `reset(seed=None, options=None) -> (obs, info)` and
`step(action) -> (obs, reward, terminated, truncated, info)`. With gymnasium installed the environments are
gymnasium.Env subclasses with gymnasium.spaces.Box spaces; without it (it is not a Debian package) they follow the
same API with a small Box of the same fields (low, high, shape, dtype, sample, contains).

Observations: one row per automated vehicle, in road order, [own speed m/s, leader speed m/s, gap m] (the inputs of
the next step, Simulation.observe). Actions: one acceleration per automated vehicle, m/s^2, held for
`action_every` steps; the engine applies the group's limits and noise as to any model. Reward (reward.py, weights
in reward.Reward, the `reward` argument): fuel of the automated vehicles and the humans behind them from the
classes' energy models (g/s per vehicle), minus gap-bound and comfort penalties; info["reward_terms"] has each term
(their sum is the reward). VectorEnv (vector.py) steps many of them in C at once."""
import numpy as np

from .batch import INFO, RlBatch
from .reward import Reward
from .scenario import Scenario
from .simulation import Simulation

try:
    import gymnasium as _gym
    from gymnasium import spaces as _spaces
except ImportError:
    _gym = None


class Box:
    """The fields of gymnasium.spaces.Box the environments use, when gymnasium is not installed."""

    def __init__(self, low, high, shape, dtype=np.float64):
        self.low = np.full(shape, low, dtype)
        self.high = np.full(shape, high, dtype)
        self.shape, self.dtype = tuple(shape), np.dtype(dtype)

    def sample(self, rng=None):
        rng = rng or np.random.default_rng()
        lo = np.where(np.isfinite(self.low), self.low, -1e3)
        hi = np.where(np.isfinite(self.high), self.high, 1e3)
        return rng.uniform(lo, hi).astype(self.dtype)

    def contains(self, x):
        x = np.asarray(x)
        return x.shape == self.shape and bool(np.all(x >= self.low) and np.all(x <= self.high))

    def __repr__(self):
        return f"Box({self.low.min()}, {self.high.max()}, {self.shape}, {self.dtype})"


def _box(low, high, shape):
    if _gym is not None:
        return _spaces.Box(low=low, high=high, shape=shape, dtype=np.float64)
    return Box(low, high, shape)


def episode_ended(t_s, t0_s, horizon_s):
    """Whether an episode that began at t0_s has reached its horizon at t_s (arrays or numbers; the same operations
    in every environment, so that a VectorEnv truncates where the environments alone do)."""
    return t_s - t0_s >= horizon_s - 1e-9


_Base = _gym.Env if _gym is not None else object
# Steps between the runs' time-series records: nothing reads them (the runs write no file), and a record every
# step costs a quarter of a 22-vehicle ring's step.
_RECORD_STEPS = 1000


class _ExternalEnv(_Base):
    """What both environments share: the run, the automated group, the observation, the action and the reward."""

    metadata = {"render_modes": []}
    AV = "av"  # the external driver group's name in the generated scenarios

    def __init__(self, n_av, accel_min_mps2, accel_max_mps2, horizon_s, dt_s, action_every, threads, reward):
        self.n_av, self.horizon_s, self.dt_s, self.action_every = n_av, horizon_s, dt_s, int(action_every)
        self.threads = threads
        self.reward = reward if reward is not None else Reward()
        self.observation_space = _box(0.0, np.inf, (n_av, 3))
        self.action_space = _box(accel_min_mps2, accel_max_mps2, (n_av,))
        self.sim = None
        self.np_random = np.random.default_rng()

    # The scenario of an episode (a dict), drawn with self.np_random.
    def _scenario(self):
        raise NotImplementedError

    def reset(self, seed=None, options=None):
        if seed is not None:
            self.np_random = np.random.default_rng(seed)
        self.close()
        self.scenario_dict = self._scenario()  # the episode's scenario, as drawn
        self.sim = Simulation(Scenario.from_dict(self.scenario_dict), threads=self.threads)
        self._warm()
        self.t0 = self.sim.t
        space = self.action_space
        self._rl = RlBatch([self.sim], [self.AV], self.reward, self.action_every, self.dt_s,
                           bounds=(space.low, space.high))
        if self._rl.n_rows != self.n_av:
            raise RuntimeError(f"{self._rl.n_rows} automated vehicles on the road, expected {self.n_av}")
        self._u = np.empty(self.n_av)
        self._step_rl = self._rl.stepper(self._u, 1)
        return self._rl.obs.reshape(self.n_av, 3).copy(), {"t": self.sim.t}

    def _warm(self):
        """Steps before the agent acts (the automated vehicles drive as acc meanwhile)."""

    def step(self, action):
        if getattr(self, "_rl", None) is None:
            raise RuntimeError("step() before reset() (or after close())")
        u = np.asarray(action, np.float64)
        self._u[...] = u if u.shape == self._u.shape else u.reshape(self._u.shape)
        self._step_rl()  # the commands clipped to the action space in C (RlBatch's bounds)
        rl, t = self._rl, self.sim.t
        info = rl.info[0].tolist()
        out = {"t": t, "fuel_rate_gps": info[3], "mean_speed_mps": info[4],
               "reward_terms": {k: info[i] for i, k in enumerate(INFO[:3])}}
        truncated = episode_ended(t, self.t0, self.horizon_s)
        return rl.obs.reshape(self.n_av, 3).copy(), float(rl.reward[0]), False, truncated, out

    def close(self):
        if getattr(self, "_rl", None) is not None:
            self._rl.close()
            self._rl = None
        if self.sim is not None:
            self.sim.close()
            self.sim = None


class RingEnv(_ExternalEnv):
    """The ring of Flow and Wu et al. (2017): n_vehicles IDM drivers with acceleration noise, n_av of them
    automated (spread evenly), the ring's length drawn uniformly from length_range_m at every reset. The automated
    vehicles drive as `acc` during warmup_s, then the agent sets their accelerations for horizon_s."""

    def __init__(self, n_vehicles=22, n_av=1, length_range_m=(220.0, 270.0), horizon_s=300.0, warmup_s=60.0,
                 dt_s=0.1, action_every=1, noise_mps2=0.2, vehicle_class="midsize_sedan", threads=1,
                 accel_range_mps2=(-3.0, 3.0), reward=None):
        super().__init__(n_av, accel_range_mps2[0], accel_range_mps2[1], horizon_s, dt_s, action_every, threads,
                         reward)
        self.n_vehicles, self.length_range_m, self.warmup_s = n_vehicles, tuple(length_range_m), warmup_s
        self.noise_mps2, self.vehicle_class = noise_mps2, vehicle_class

    def _scenario(self):
        length = float(self.np_random.uniform(*self.length_range_m))
        return {
            "name": "ring_env", "seed": int(self.np_random.integers(1, 2**31)),
            "road": {"length_m": length},
            # One step more than the episode: the run never reaches its end inside an episode. Its statistics
            # window opens after the episode: the run never ends and writes no file, so no summary is ever made of
            # its per-vehicle statistics, and the steps keep none.
            "time": {"duration_s": self.warmup_s + self.horizon_s + 2 * self.dt_s, "dt_s": self.dt_s,
                     "output_interval_s": _RECORD_STEPS * self.dt_s,
                     "warmup_s": self.warmup_s + self.horizon_s + self.dt_s},
            "fleet": {"vehicles": self.n_vehicles, "placement": "interleaved",
                      "classes": [{"class": self.vehicle_class, "fraction": 1.0}],
                      "drivers": [{"name": "human", "model": "idm", "count": self.n_vehicles - self.n_av,
                                   "noise_mps2": self.noise_mps2},
                                  {"name": self.AV, "model": "external", "count": self.n_av}]},
            "output": {"trajectories": False},
        }

    def _warm(self):
        n = int(round(self.warmup_s / self.dt_s))
        if n:
            self.sim.step(n)


class TrajectoryEnv(_ExternalEnv):
    """The CIRCLES training setting: a platoon of n_vehicles on a corridor, an automated vehicle after every
    humans_per_av humans (interleaved), behind a virtual leader replaying a speed trace (time_s, speed_mps: a CSV
    path, or two arrays), such as a measured highway trajectory or a drive cycle. The leader starts 200 m inside a
    road long enough that no one leaves during the episode and holds the trace's first speed while the platoon
    enters (one vehicle a second) and closes up behind it; the episode then replays the trace (horizon_s: its
    length by default)."""

    def __init__(self, trace, n_vehicles=20, humans_per_av=4, horizon_s=None, dt_s=0.1, action_every=1,
                 noise_mps2=0.0, vehicle_class="midsize_sedan", threads=1, accel_range_mps2=(-3.0, 3.0),
                 reward=None):
        if isinstance(trace, (str, bytes)) or hasattr(trace, "__fspath__"):
            data = np.loadtxt(trace, delimiter=",", skiprows=1, ndmin=2)
            t, v = data[:, 0], data[:, 1]
        else:
            t, v = (np.asarray(x, np.float64) for x in trace)
        self.trace_t, self.trace_v = t - t[0], v
        n_av = n_vehicles // (humans_per_av + 1)
        if n_av < 1:
            raise ValueError(f"n_vehicles {n_vehicles} holds no automated vehicle at one per {humans_per_av} humans")
        span = float(self.trace_t[-1])
        super().__init__(n_av, accel_range_mps2[0], accel_range_mps2[1], horizon_s or span, dt_s, action_every,
                         threads, reward)
        self.n_vehicles, self.humans_per_av = n_vehicles, humans_per_av
        self.noise_mps2, self.vehicle_class = noise_mps2, vehicle_class
        # The leader's path: the fill at the trace's first speed, then the trace; 1 km to spare.
        self.length_m = 200.0 + float(self.trace_v[0]) * self._fill_s() + float(np.trapz(self.trace_v, self.trace_t))
        self.length_m += 1000.0

    def _scenario(self):
        share = self.n_av / self.n_vehicles
        fill_s = self._fill_s()
        return {
            "name": "trajectory_env", "seed": int(self.np_random.integers(1, 2**31)),
            "road": {"type": "corridor", "length_m": self.length_m},
            "time": {"duration_s": fill_s + self.horizon_s + 2 * self.dt_s, "dt_s": self.dt_s,
                     "output_interval_s": _RECORD_STEPS * self.dt_s, "warmup_s": 0},
            "fleet": {"placement": "interleaved", "classes": [{"class": self.vehicle_class, "fraction": 1.0}],
                      "drivers": [{"name": "human", "model": "idm", "fraction": 1.0 - share,
                                   "noise_mps2": self.noise_mps2},
                                  {"name": self.AV, "model": "external", "fraction": share}]},
            "corridor": {"inflow": {"flow_vph": 3600, "arrivals": "deterministic", "vehicles": self.n_vehicles},
                         "outflow": {"type": "leader", "offset_m": 200.0 - self.length_m,
                                     "points": [[fill_s + float(t), float(v)]
                                                for t, v in zip(self.trace_t, self.trace_v)]}},
            "output": {"trajectories": False},
        }

    def _fill_s(self):
        """Time for the platoon to enter (one vehicle a second) and close up behind the leader."""
        return 3.0 * self.n_vehicles + 60.0

    def _warm(self):
        """The fill: the platoon enters and forms behind the leader, which holds the trace's first speed (the
        automated vehicles drive as acc meanwhile); the trace starts with the episode."""
        self.sim.step(int(round(self._fill_s() / self.dt_s)))
        if self.sim.n_vehicles < self.n_vehicles:
            raise RuntimeError(f"{self.sim.n_vehicles} of {self.n_vehicles} vehicles entered during the fill")


# VectorEnv steps these environments in batches (vector.py imports this module: imported last).
from .vector import VectorEnv  # noqa: E402,F401
