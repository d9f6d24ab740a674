"""The baseline of the RL-environment benchmark (bench/README.md, "RL environments"): wavefuel's RingEnv written
with numpy, vectorised over environments, as a Python user would write it without wavefuel. State arrays (B, N),
vehicle i + 1 leading vehicle i and the last vehicle led by vehicle 0 one lap ahead, as wavefuel's ring. One step
of dt_s, per vehicle, in the engine's order of operations (docs/models.md, docs/scenarios.md):
- gap = (x_leader - car length) - x; IDM (Treiber et al. 2000) with delta = 4 for the humans, the commanded
  acceleration for the automated vehicles; plus noise_mps2 x N(0, 1) for the humans (numpy's generator: the
  engine's counter-based deviates differ, so the agreement check runs without noise); clipped to
  [-decel_max, accel_max];
- the ballistic update with exact stopping (Treiber & Kanagaraj 2015);
- the reward of wavefuel.envs.Reward, with the light-duty CIRCLES polynomial energy model (Lee et al.) written here
  from the class's parameters (flat road).
No overlap repair (wavefuel's, for vehicles that would overlap after a step): the agreement check would show one."""
import numpy as np


def idm_accel(idm, v, vl, gap):
    """IDM (delta 4) acceleration, m/s^2, of idm = (v0_mps, T_s, s0_m, a_mps2, b_mps2) at speed v, leader speed vl
    and gap (m), in the engine's order of operations (src/models/cf/idm.c), the gap floored at 1 mm."""
    v0, T, s0, a, b = idm
    x = v / v0
    x2 = x * x
    dyn = v * T + v * (v - vl) / (2.0 * np.sqrt(a * b))
    s_star = s0 + np.where(dyn > 0.0, dyn, 0.0)
    r = s_star / np.where(gap > 1e-3, gap, 1e-3)
    return a * (1.0 - x2 * x2 - r * r)


def circles_fuel(e, v, a):
    """CIRCLES light-duty fuel rate (g/s) on a flat road, the model's operations in their order; e: the class's
    parameters {key: value}."""
    v = np.maximum(v, 0.0)
    P = e["p0"] + e["p1"] * v + e["p2"] * v * v
    Q = e["q0"] + e["q1"] * np.maximum(v, 1e-12)
    with np.errstate(divide="ignore", invalid="ignore"):
        floor = -P / (2.0 * Q)
    ap = np.where(np.isnan(floor), a, np.maximum(a, floor))
    f = (e["c0"] + e["c1"] * v + e["c2"] * v * v + e["c3"] * v * v * v + e["p0"] * a + e["p1"] * a * v
         + e["p2"] * a * v * v + e["q0"] * ap * ap + e["q1"] * ap * ap * v)
    f = np.maximum(f, np.where(v <= e["v_c"], e["beta"], 0.0))
    a_cut = e["a0"] + e["a1"] * v + e["a3"] * v * v
    f = np.where((v > e["v_c"]) & (a <= a_cut), 0.0, f)
    return np.where((v < 0.1) & (np.abs(a) < 0.01), e["f_idle"], f)


def reward_terms(rw, rate, gap_m, a_av, a_prev, dt):
    """The terms of wavefuel.envs.Reward rw (B,) and a_av (the next a_prev) from the mean fuel rate (B,) of the
    vehicles in scope, the automated vehicles' gaps and accelerations (B, n_av) and their previous accelerations
    a_prev (NaN on an episode's first action: no jerk)."""
    g = gap_m
    viol = np.maximum(rw.gap_range_m[0] - g, 0.0) ** 2 + np.maximum(g - rw.gap_range_m[1], 0.0) ** 2
    jerk = np.where(np.isnan(a_prev), 0.0, (a_av - a_prev) / dt)
    return {"fuel": -rw.w_fuel * rate, "gap": -rw.w_gap * viol.mean(axis=1),
            "comfort": -(rw.w_accel * (a_av * a_av).mean(axis=1) + rw.w_jerk * (jerk * jerk).mean(axis=1))}, a_av


class NumpyRing:
    """B rings of N vehicles, automated ones where `av` (a boolean (N,) mask, the same for all rings). idm: the
    humans' (v0_mps, T_s, s0_m, a_mps2, b_mps2); limits: (accel_max, decel_max) m/s^2 of each group
    (human, automated); energy: the class's CIRCLES parameters {key: value}; car_m its length; reward: a
    wavefuel.envs.Reward; action_range: the action space's (low, high)."""

    def __init__(self, length_m, av, idm, limits, energy, car_m, dt_s, noise_mps2, reward, action_range, seed=0):
        self.L = np.asarray(length_m, np.float64)[:, None]
        self.av = np.asarray(av, bool)
        self.B, self.N = self.L.shape[0], self.av.size
        self.idm = idm
        (hmax, hdec), (amax, adec) = limits
        self.amax = np.where(self.av, amax, hmax)
        self.dmax = np.where(self.av, adec, hdec)
        self.e, self.car, self.dt, self.noise = energy, car_m, dt_s, noise_mps2
        self.rw, self.lo, self.hi = reward, action_range[0], action_range[1]
        self.rng = np.random.default_rng(seed)
        self.x = self.v = None

    def set_state(self, x_m, v_mps):
        self.x, self.v = np.array(x_m, np.float64), np.array(v_mps, np.float64)
        self.a_prev = np.full((self.B, int(self.av.sum())), np.nan)

    def _lead(self):
        lead_x = np.concatenate((self.x[:, 1:], self.x[:, :1] + self.L), axis=1)
        lead_v = np.concatenate((self.v[:, 1:], self.v[:, :1]), axis=1)
        return lead_x - self.car - self.x, lead_v

    def observe(self):
        gap, vl = self._lead()
        return np.stack((self.v[:, self.av], vl[:, self.av], gap[:, self.av]), axis=-1)

    def fuel(self, v, a):
        return circles_fuel(self.e, v, a)

    def step(self, action):
        """One step of every ring with the automated vehicles' commands action (B, n_av); returns (obs, reward,
        terms) as wavefuel's VectorEnv (every vehicle in the fuel's scope: a ring)."""
        gap, vl = self._lead()
        v, dt = self.v, self.dt
        acc = idm_accel(self.idm, v, vl, gap)
        if self.noise > 0.0:
            acc = acc + np.where(self.av, 0.0, self.noise) * self.rng.standard_normal(acc.shape)
        acc[:, self.av] = np.clip(action, self.lo, self.hi)
        acc = np.maximum(np.minimum(acc, self.amax), -self.dmax)
        vn = v + acc * dt
        run = vn >= 0.0
        dx_run = v * dt + 0.5 * acc * dt * dt
        dx_stop = -(v * v) / (2.0 * np.where(acc < 0.0, acc, -1.0))
        self.x = self.x + np.where(run, dx_run, dx_stop)
        self.v = np.where(run, vn, 0.0)
        obs = self.observe()
        a = (self.v - v) / dt
        terms, self.a_prev = reward_terms(self.rw, self.fuel(v, a).mean(axis=1), obs[:, :, 2], a[:, self.av],
                                          self.a_prev, dt)
        return obs, terms["fuel"] + terms["gap"] + terms["comfort"], terms
