"""The reward of the RL environments (envs.py, vector.py): its weights and bounds. The library computes it
(include/wavefuel/rl.h, batch.py), run by run in a fixed order: an environment alone and in a VectorEnv get the
same bits.

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

from ._lib import WfRlReward

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

    def _c(self):
        return WfRlReward(int(self.fuel_scope == "all"), self.w_fuel, self.gap_range_m[0], self.gap_range_m[1],
                          self.w_gap, self.w_accel, self.w_jerk)

