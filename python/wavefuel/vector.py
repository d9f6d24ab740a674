"""VectorEnv: B environments (RingEnv or TrajectoryEnv, envs.py) stepped together inside C, the Gymnasium vector API:
observations (B, n_av, 3), actions (B, n_av), rewards, terminations and truncations (B,), infos a dict of arrays.
One action of all environments is one library call (batch.py, include/wavefuel/rl.h): every automated vehicle of
every environment takes its command from one array, and in parallel over environments on OpenMP threads each run
steps (single-threaded inside) and computes its observation and reward (reward.py): an environment gives the bits it
gives alone."""
import numpy as np

from . import _lib
from .batch import INFO, RlBatch
from .envs import RingEnv, _box, episode_ended


class VectorEnv:
    """n_envs environments `env(**kwargs, **per_env[i])` (env: RingEnv, TrajectoryEnv or a callable returning
    one; per_env: optional list of n_envs dicts, e.g. different ring lengths or traces), stepped on up to `threads`
    OpenMP threads (None: the library's default, $OMP_NUM_THREADS or all cores): how many of them each action takes
    is chosen by timing the actions, every `thread_check` of them (None: the library's default, 1024; 0: always
    `threads`), because on a machine whose cores other processes use all threads can be slower than one; results
    never depend on it. The environments must agree on the number of automated vehicles, dt_s and action_every.

    reset(seed=None, options=None) -> (obs, infos): seed an int (environment i gets seed + i), a list of n_envs
    seeds, or None (each environment draws from its own generator). step(actions) -> (obs, rewards, terminated,
    truncated, infos). Autoreset in the same step (Gymnasium's "same-step" mode): an environment whose episode
    ended is reset at once and its row of obs is the new episode's first observation; infos["final_obs"] and
    infos["final_info"] hold, for those environments, the last observation and info of the ended episode (None
    for the others). infos: "t", "fuel_rate_gps", "mean_speed_mps" arrays (n_envs,), "reward_terms" a dict of
    such arrays, each key K with a boolean mask "_K" (Gymnasium's convention). The actions are clipped to
    action_space in C; terminated, and truncated while no episode ends, are one read-only all-False array."""

    metadata = {"autoreset_mode": "SameStep"}

    def __init__(self, n_envs, env=RingEnv, threads=None, per_env=None, thread_check=None, **kwargs):
        if int(n_envs) < 1:
            raise ValueError(f"n_envs must be at least 1 (got {n_envs})")
        self.num_envs = int(n_envs)
        per_env = per_env or [{}] * self.num_envs
        if len(per_env) != self.num_envs:
            raise ValueError(f"per_env has {len(per_env)} entries for {self.num_envs} environments")
        kwargs.setdefault("threads", 1)  # each run single-threaded: the batch is parallel over runs
        self.envs = [env(**dict(kwargs, **p)) for p in per_env]
        e0 = self.envs[0]
        for i, e in enumerate(self.envs):
            if (e.n_av, e.dt_s, e.action_every) != (e0.n_av, e0.dt_s, e0.action_every):
                raise ValueError(f"environment {i}: n_av {e.n_av}, dt_s {e.dt_s}, action_every {e.action_every} "
                                 f"differ from environment 0's ({e0.n_av}, {e0.dt_s}, {e0.action_every})")
        if any(repr(e.reward) != repr(e0.reward) for e in self.envs):
            raise ValueError("the environments' rewards differ: give `reward` for all, not in per_env")
        self.threads = int(threads) if threads is not None else _lib.max_threads()
        if not 1 <= self.threads <= 4096:
            raise ValueError(f"threads must be an integer in [1, 4096] (got {threads})")
        if thread_check is not None and int(thread_check) < 0:
            raise ValueError(f"thread_check must be >= 0 (got {thread_check})")
        self.thread_check = None if thread_check is None else int(thread_check)
        self.n_av, self.dt_s, self.action_every = e0.n_av, e0.dt_s, e0.action_every
        self.single_observation_space, self.single_action_space = e0.observation_space, e0.action_space
        self.observation_space = _box(0.0, np.inf, (self.num_envs, self.n_av, 3))
        self._low = np.stack([e.action_space.low for e in self.envs])
        self._high = np.stack([e.action_space.high for e in self.envs])
        self.action_space = _box(self._low, self._high, (self.num_envs, self.n_av))
        self._u = np.empty((self.num_envs, self.n_av))
        self._all = np.ones(self.num_envs, bool)
        self._all.flags.writeable = False
        self._none = np.zeros(self.num_envs, bool)  # no termination, no truncation: read-only, shared by the steps
        self._none.flags.writeable = False
        self._batch = None
        self._governed = (0, 0)
        self._side = 0

    @property
    def side_by_side(self):
        """Actions so far whose steps the environments' rings took side by side in shared blocks of the kernel
        (docs/python.md); the others were stepped one run at a time. The same bits either way."""
        return self._side + (self._batch.gang_calls() if self._batch is not None else 0)

    @property
    def thread_governor(self):
        """(probes, switches): the thread governor's probes of the other thread count and its switches so far."""
        now = self._batch.governor() if self._batch is not None else (0, 0)
        return self._governed[0] + now[0], self._governed[1] + now[1]

    def _rebuild(self, done=None):
        """The batch after the environments `done` (None: all) were reset (new runs); the others keep their
        previous action's accelerations (the jerk's)."""
        prev = None
        if self._batch is not None:
            prev = self._batch.prev_accel.reshape(self.num_envs, self.n_av).copy()
            self._governed = self.thread_governor
            self._side = self.side_by_side
            self._batch.close()
        self._batch = RlBatch([e.sim for e in self.envs], [e.AV for e in self.envs], self.envs[0].reward,
                              self.action_every, self.dt_s, self.thread_check, bounds=(self._low, self._high))
        if done is not None:
            prev[done] = np.nan
            self._batch.prev_accel[:] = prev.ravel()
        self._steps = np.array([e.sim.steps_done for e in self.envs], np.int64)
        self._t0 = np.array([e.t0 for e in self.envs])
        self._horizon = np.array([e.horizon_s for e in self.envs])
        # Actions until the first environment's episode ends (step's test, in the same floating-point operations):
        # until then step() skips the test, and its array arithmetic (a third of a 64-ring call's Python time).
        self._left = min(self._actions_left(i) for i in range(self.num_envs))
        self._step_batch = self._batch.stepper(self._u, self.threads)
        self._obs_size, self._obs_shape = self._batch.n_rows * 3, (self.num_envs, self.n_av, 3)

    def _truncated(self):
        return episode_ended(self._steps * self.dt_s, self._t0, self._horizon)

    def _actions_left(self, i):
        """Actions environment i takes before its episode is truncated (at least 1)."""
        steps0, t0, horizon, every = int(self._steps[i]), self._t0[i], self._horizon[i], self.action_every
        ends = lambda k: episode_ended(float(steps0 + k * every) * self.dt_s, t0, horizon)  # noqa: E731
        est = (horizon + t0 - steps0 * self.dt_s) / (every * self.dt_s)
        if not est < 2.0**40:  # beyond any run's steps (time.duration_s <= 1e9 s), or not a number: not in reach
            return 2**62
        k = max(1, int(np.ceil(est)) - 2)
        while k > 1 and ends(k - 1):
            k -= 1
        while not ends(k):
            k += 1
        return k

    def reset(self, seed=None, options=None):
        if seed is None or np.isscalar(seed):
            seeds = [None if seed is None else int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"{len(seeds)} seeds for {self.num_envs} environments")
        for e, s in zip(self.envs, seeds):
            e.reset(seed=s, options=options)
        self._rebuild()
        obs = self._batch.obs.reshape(self.num_envs, self.n_av, 3).copy()
        return obs, {"t": self._steps * self.dt_s, "_t": self._all}

    def step(self, actions):
        if self._batch is None:
            raise RuntimeError("VectorEnv.step before reset()")
        if type(actions) is np.ndarray and actions.shape == self._u.shape:
            self._u[...] = actions
        else:
            self._u[...] = np.asarray(actions, np.float64).reshape(self._u.shape)
        self._step_batch()  # the commands clipped to the action space in C (RlBatch's bounds)
        # one copy of the batch's results (overwritten by the next step), then views of it
        out, n, k = self._batch.out.copy(), self.num_envs, self._obs_size
        obs, r, cols = out[:k].reshape(self._obs_shape), out[k:k + n], out[k + n:].reshape(n, len(INFO)).T
        infos = _infos(*cols, self._all)
        t = infos["t"]  # each run's time, as Simulation.t: steps done x dt
        self._left -= 1
        if self._left > 0:
            return obs, r, self._none, self._none, infos
        self._steps = np.array([e.sim.steps_done for e in self.envs], np.int64)
        truncated = self._truncated()
        if truncated.any():
            infos.update(self._autoreset(np.flatnonzero(truncated), obs, t, cols))
            obs = self._batch.obs.reshape(self.num_envs, self.n_av, 3).copy()
        else:
            self._left = 1  # not reached: _actions_left is the exact test's
        return obs, r, self._none, truncated, infos

    def _autoreset(self, done, obs, t, cols):
        """Reset the environments `done` (each from its own generator) and return final_obs / final_info with their
        masks."""
        final_obs = np.full(self.num_envs, None, object)
        final_info = np.full(self.num_envs, None, object)
        for i in done:
            final_obs[i] = obs[i].copy()
            final_info[i] = {"t": float(t[i]), "fuel_rate_gps": float(cols[3][i]), "mean_speed_mps": float(cols[4][i]),
                             "reward_terms": {k: float(cols[j][i]) for j, k in enumerate(INFO[:3])}}
            self.envs[i].reset()
        self._rebuild(done)
        mask = np.zeros(self.num_envs, bool)
        mask[done] = True
        return {"final_obs": final_obs, "_final_obs": mask, "final_info": final_info, "_final_info": mask.copy()}

    def close(self):
        if self._batch is not None:
            self._batch.close()
            self._batch = None
        for e in self.envs:
            e.close()


def _infos(fuel, gap, comfort, fuel_rate, mean_speed, t, every):
    """Gymnasium's vector infos of a step: "t", "fuel_rate_gps", "mean_speed_mps" (n_envs,) and "reward_terms" (a dict
    of such arrays) from the batch's info columns (INFO, in its order), each key K with its boolean mask "_K" (every:
    a read-only all-True mask, shared)."""
    return {"t": t, "_t": every, "fuel_rate_gps": fuel_rate, "_fuel_rate_gps": every,
            "mean_speed_mps": mean_speed, "_mean_speed_mps": every,
            "reward_terms": {"fuel": fuel, "_fuel": every, "gap": gap, "_gap": every,
                             "comfort": comfort, "_comfort": every}, "_reward_terms": every}
