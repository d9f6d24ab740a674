"""The reward of the RL environments (envs.py, vector.py), computed for a batch of environments at once (one
environment is a batch of one: the same operations, so an environment alone and in a VectorEnv get the same bits).

reward = fuel + gap + comfort, each term <= 0, per action (action_every steps of dt_s, lasting dt = dt_s x
action_every):
- fuel = -w_fuel x the mean fuel rate (g/s per vehicle) of the vehicles in scope: each vehicle's class energy model
  (wavefuel.energy, flat road) at its speed at the action's start and the acceleration that took it to its speed
  at the end, (v_end - v_start) / dt. Scope "platoon": the automated vehicles and the humans behind them (on a
  ring every vehicle; on a corridor every vehicle from the front-most automated one back); "all": every vehicle.
- gap = -w_gap x the mean over the automated vehicles of the squared violation (m^2) of the gap bounds
  gap_range_m = (min, max) by their bumper-to-bumper gap at the action's end: (min - gap)^2 below min,
  (gap - max)^2 above max, 0 between.
- comfort = -(w_accel x mean a^2 + w_jerk x mean j^2) over the automated vehicles: a = (v_end - v_start) / dt
  (m/s^2) the acceleration they drove, j = (a - a of the previous action) / dt (m/s^3; 0 on an episode's first
  action)."""
import numpy as np

from .energy import vehicle_class

SCOPES = ("platoon", "all")


class Reward:
    """The reward's weights and bounds (the module's docstring gives the terms). Units: w_fuel per g/s, w_gap per
    m^2, w_accel per (m/s^2)^2, w_jerk per (m/s^3)^2. Defaults weigh the terms so that a 1 m/s^2 acceleration
    (0.02) or a 5 m gap violation (0.25) cost a fraction of a car's fuel rate at highway speed (about 1 g/s)."""

    def __init__(self, fuel_scope="platoon", w_fuel=1.0, gap_range_m=(5.0, 100.0), w_gap=0.01, w_accel=0.02,
                 w_jerk=0.001):
        if fuel_scope not in SCOPES:
            raise ValueError(f"fuel_scope must be one of {', '.join(SCOPES)} (got {fuel_scope!r})")
        lo, hi = (float(x) for x in gap_range_m)
        if not 0.0 <= lo < hi:
            raise ValueError(f"gap_range_m must be (min, max) with 0 <= min < max, m (got {gap_range_m!r})")
        weights = dict(w_fuel=w_fuel, w_gap=w_gap, w_accel=w_accel, w_jerk=w_jerk)
        for k, w in weights.items():
            if not (np.isfinite(w) and w >= 0):
                raise ValueError(f"{k} must be a finite weight >= 0 (got {w!r})")
        self.fuel_scope, self.gap_range_m = fuel_scope, (lo, hi)
        self.w_fuel, self.w_gap, self.w_accel, self.w_jerk = (float(w) for w in weights.values())

    def __repr__(self):
        return (f"Reward(fuel_scope={self.fuel_scope!r}, w_fuel={self.w_fuel}, gap_range_m={self.gap_range_m}, "
                f"w_gap={self.w_gap}, w_accel={self.w_accel}, w_jerk={self.w_jerk})")

    def scope(self, group_id, av_group, ring):
        """1.0 for the vehicles of one road (group ids in road order: a ring's ring order, a corridor's front first)
        whose fuel counts, else 0.0."""
        if self.fuel_scope == "all" or ring:  # on a ring every vehicle is behind an automated one
            return np.ones(group_id.size)
        av = np.flatnonzero(group_id == av_group)
        first = av[0] if av.size else group_id.size  # front first: the first automated vehicle and those behind
        return (np.arange(group_id.size) >= first).astype(np.float64)


class Layout:
    """What the reward needs of a batch of environments that stays fixed during their episodes: the vehicles'
    classes and scope, runs one after the other (each run's vehicles in road order), and where each run's vehicles
    and automated vehicles start. parts: (class names of each vehicle's class index, class ids, scope) per run."""

    def __init__(self, parts, n_av, dt_s):
        names = sorted({n for p in parts for n in p[0]})
        self.classes = [vehicle_class(n) for n in names]
        cls = [np.array([names.index(p[0][c]) for c in range(len(p[0]))])[np.asarray(p[1], np.intp)] for p in parts]
        self.cls = np.concatenate(cls)
        self.masks = [self.cls == k for k in range(len(names))] if len(names) > 1 else None
        self.scope = np.concatenate([p[2] for p in parts])
        n_veh = np.array([len(p[1]) for p in parts])
        self.n_scope = np.array([p[2].sum() for p in parts])
        self.n_veh, self.n_av = n_veh.astype(np.float64), np.asarray(n_av, np.float64)
        self.veh_off = np.concatenate(([0], np.cumsum(n_veh)[:-1]))
        self.av_off = np.concatenate(([0], np.cumsum(np.asarray(n_av))[:-1])).astype(np.intp)
        self.dt_s = float(dt_s)


def fuel_rates(lay, v0, v1):
    """Each vehicle's fuel rate (g/s) over the action (the module's docstring)."""
    a = (v1 - v0) / lay.dt_s
    if lay.masks is None:
        return lay.classes[0].fuel(v0, a, 0.0)
    out = np.empty(v0.shape)
    for vc, m in zip(lay.classes, lay.masks):
        out[m] = vc.fuel(v0[m], a[m], 0.0)
    return out


def terms(rw, lay, v0, v1, obs0, obs1, a_prev):
    """The reward of each environment of a batch and its terms: speeds of every vehicle at the action's start and
    end (v0, v1), the automated vehicles' observations then (obs0, obs1: rows [speed, leader speed, gap]) and their
    accelerations of the previous action (a_prev, NaN on an episode's first action). Returns (reward, {"fuel",
    "gap", "comfort"}, mean fuel rate of the scope g/s, mean speed m/s, the automated vehicles' accelerations)."""
    rate = np.add.reduceat(fuel_rates(lay, v0, v1) * lay.scope, lay.veh_off) / lay.n_scope
    lo, hi = rw.gap_range_m
    gap = obs1[:, 2]
    viol = np.maximum(lo - gap, 0.0) ** 2 + np.maximum(gap - hi, 0.0) ** 2
    a = (obs1[:, 0] - obs0[:, 0]) / lay.dt_s
    jerk = np.where(np.isnan(a_prev), 0.0, (a - a_prev) / lay.dt_s)
    mean_av = lambda x: np.add.reduceat(x, lay.av_off) / lay.n_av
    t = {"fuel": -rw.w_fuel * rate, "gap": -rw.w_gap * mean_av(viol),
         "comfort": -(rw.w_accel * mean_av(a * a) + rw.w_jerk * mean_av(jerk * jerk))}
    reward = t["fuel"] + t["gap"] + t["comfort"]
    speed = np.add.reduceat(v1, lay.veh_off) / lay.n_veh
    return reward, t, rate, speed, a
