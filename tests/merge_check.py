"""Checks of on-ramp merges with cooperation at the lane's end (docs/lanes.md, "Lanes that end", "Cooperation") for
tests/t_merge.sh, one subcommand per check; each exits non-zero with the reason on failure and prints a one-line
account of what it measured on success. Every check recomputes what it compares from the trajectories in numpy:
IDM (Treiber, Hennecke & Helbing 2000) and MOBIL's mandatory rule written here from their equations and the
parameters in the result's scenario text (unset keys: the defaults documented in docs/scenarios.md, docs/lanes.md).

  waves HIGH.h5 LOW.h5 X0 XM XD T0        stop-and-go waves on the main lanes upstream of the merge (X0 <= x < XM)
                                          after T0 at high demand, none at low demand; free flow downstream (x >= XD)
                                          at both (thresholds: V_* below)
  accel FILE.h5                           frames every step, noise off: every vehicle's acceleration at every step
                                          equals its own-lane IDM, capped where the cooperation rule recomputed here
                                          makes it yield (and only there)
  mandatory FILE.h5                       frames every step: every merge out of the merge lane is a change MOBIL's
                                          mandatory rule allows, and every merge-lane vehicle with a gap that rule
                                          accepts takes it (unless another vehicle took that gap in that step)
  coop_effect ON.h5 OFF.h5 X0 XM T0       cooperation on / off (coop_decel_mps2 0) at the same demand: merges, the
                                          merge lane's queue, the ramp's entries and the main lanes upstream
  conservation FILE.h5                    frames every step: tests/corridor_lanes_check.py's `physical` method with the
                                          ramp's entries at start_m, each lane's vehicles at every step and record from
                                          entries, exits and changes, the merge lane's rules
  yields FILE.h5 MIN_LANE_N MIN_YIELDS    frames of a noisy run: accelerations equal, to the bit, to a recomputed
                                          cooperation bound (a yield that binds: noise and own-lane IDM cannot give
                                          that value), at least MIN_YIELDS of them in a lane of more than MIN_LANE_N
"""
import sys

import h5py
import numpy as np
import yaml

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from corridor_lanes_check import LANE_KEY, frames, step_of  # noqa: E402

# documented defaults (docs/scenarios.md: IDM, drivers; docs/lanes.md: MOBIL; include/wavefuel/corridor.h)
IDM_DEFAULTS = {"v0_mps": 30.0, "T_s": 1.0, "s0_m": 2.0, "a_mps2": 1.0, "b_mps2": 1.5, "delta": 4.0}
MOBIL_DEFAULTS = {"coop_decel_mps2": 1.5, "merge_range_m": 300.0, "b_mandatory_mps2": 8.0}
ACCEL_MAX, DECEL_MAX = 5.0, 9.0
FREE_GAP_M = 1e5          # the front vehicle of a lane with free outflow follows a leader this far at its own speed
IDM_GAP_FLOOR_M = 1e-3    # IDM's smallest gap (src/models/cf/idm.c)

# check 1's definitions (t_merge.sh's header states them with the figures measured)
V_STOP, V_GO = 0.5, 2.0   # a stop: below V_STOP; the stop ends (one stop-go cycle) once the speed exceeds V_GO
V_SLOW = 5.0              # vehicle-time slower than this counts as congested
V_FREE = 15.0             # free flow: every point faster than this


# ------------------------------------------------------------------------------------------------ the scenario
class Setup:
    """What the checks need from a result: the road's lanes that end, and each group's parameters."""

    def __init__(self, f):
        sc = yaml.safe_load(f["meta/scenario_text"][()].decode())
        assert not f["meta/overrides"][()], "run with --set overrides: the scenario text would not be the run's"
        co = sc["corridor"]
        ramp = co.get("on_ramp")
        assert ramp and not co.get("lane_drops"), "the checks know an on-ramp (lane 0) and no lane drops"
        self.start_m, self.end_m = float(ramp["start_m"]), float(ramp["end_m"])
        assert co.get("outflow", {}).get("type", "free") == "free", "free outflow only"
        self.speed_limit = sc["road"].get("speed_limit_mps")
        self.zones = sc["road"].get("zones")
        self.n_lanes = int(sc["road"]["lanes"]) + 1
        self.groups = []
        for g in sc["fleet"]["drivers"]:
            assert g["model"] == "idm", "IDM groups only"
            assert not g.get("heterogeneity"), "no heterogeneity: one parameter set per group"
            assert not g.get("feasible_accel") and not g.get("safety"), "a rule after the limits not recomputed here"
            p = dict(IDM_DEFAULTS, **g.get("params", {}))
            lc = g.get("lane_change", {"model": "mobil"})
            m = dict(MOBIL_DEFAULTS, **{k: v for k, v in lc.items() if k != "model"}) if lc["model"] == "mobil" else None
            self.groups.append({"idm": {k: float(v) for k, v in p.items()}, "lc": m,
                                "noise": float(g.get("noise_mps2", 0.0)),
                                "amax": float(g.get("accel_max_mps2", ACCEL_MAX)),
                                "dmax": float(g.get("decel_max_mps2", DECEL_MAX))})
        self.lengths = f["classes/length"][()]


def idm(p, gap, v, vl):
    """IDM's acceleration, term for term as src/models/cf/idm.c writes it (delta = 4 as (x^2)^2)."""
    x = v / p["v0_mps"]
    if p["delta"] == 4.0:
        x2 = x * x
        free = x2 * x2
    else:
        free = np.power(np.maximum(x, 0.0), p["delta"])
    dyn = v * p["T_s"] + v * (v - vl) / (2.0 * np.sqrt(p["a_mps2"] * p["b_mps2"]))
    s_star = p["s0_m"] + np.where(dyn > 0.0, dyn, 0.0)
    s = np.where(gap > IDM_GAP_FLOOR_M, gap, IDM_GAP_FLOOR_M)
    r = s_star / s
    return p["a_mps2"] * (1.0 - free - r * r)


def per_group(setup, gid, fn):
    """fn(group dict, mask) evaluated group by group into one array."""
    out = np.full(len(gid), np.nan)
    for g, grp in enumerate(setup.groups):
        m = gid == g
        if m.any():
            out[m] = fn(grp, m)
    return out


class Frames:
    """The trajectory points of a result with each point's step, lane, vehicle (row of /trips), group, length,
    and whether the vehicle entered at that step (entries come after the step's lane changes and cooperation)."""

    def __init__(self, path):
        self.f = f = h5py.File(path, "r")
        self.setup = Setup(f)
        self.dt, self.k, self.serial, self.row, self.bounds = frames(f)
        tr, tp = f["trajectories"], f["trips"]
        self.x, self.v, self.a = tr["x"][()], tr["v"][()], tr["a"][()]
        self.lane = tr["lane"][()].astype(np.int64)
        self.gid = tp["group_id"][()].astype(np.int64)[self.row]
        self.length = self.setup.lengths[tp["class_id"][()].astype(np.int64)][self.row]
        self.entry_step = step_of(tp["entry_time"][()], self.dt)
        self.entrant = self.entry_step[self.row] == self.k
        self.n_steps = int(f["meta/steps_done"][()])
        key = self.k * 16 + self.lane
        assert np.all(np.diff(key) >= 0), "points not lane after lane within a frame"
        self.has_leader = np.zeros(len(self.x), dtype=bool)
        self.has_leader[1:] = key[1:] == key[:-1]


def own_lane_accel(fr):
    """Each point's acceleration from its own lane: IDM behind the point before it (same frame and lane: lanes are
    written front first), the front of the merge lane behind the lane's end at rest, a main lane's front behind a
    free road (FREE_GAP_M at its own speed); then the group's limits (docs/scenarios.md: a clipped to
    [-decel_max, accel_max]). Without noise."""
    x, v, L = fr.x, fr.v, fr.length
    gap = np.full(len(x), FREE_GAP_M)
    vl = v.copy()
    ld = fr.has_leader
    gap[1:][ld[1:]] = (x[:-1] - L[:-1] - x[1:])[ld[1:]]
    vl[1:][ld[1:]] = v[:-1][ld[1:]]
    front_ramp = ~ld & (fr.lane == 0)
    gap[front_ramp] = fr.setup.end_m - x[front_ramp]
    vl[front_ramp] = 0.0
    a = per_group(fr.setup, fr.gid, lambda g, m: idm(g["idm"], gap[m], v[m], vl[m]))
    amax = np.array([g["amax"] for g in fr.setup.groups])[fr.gid]
    dmax = np.array([g["dmax"] for g in fr.setup.groups])[fr.gid]
    a = np.where(a > amax, amax, a)
    return np.where(a < -dmax, -dmax, a)


def behind_ahead(k, x, askers, cands):
    """For each asker point, the candidate point right behind it in the same frame (the last one whose x is below
    the asker's) and the one ahead of it (the first at or ahead of the asker's x); -1 where none."""
    idx = np.concatenate([askers, cands])
    typ = np.concatenate([np.zeros(len(askers), np.int64), np.ones(len(cands), np.int64)])
    o = np.lexsort((typ, x[idx], k[idx]))     # at equal x the asker first: a candidate there is not behind it
    idx, typ = idx[o], typ[o]
    pos = np.arange(len(idx))
    last = np.maximum.accumulate(np.where(typ == 1, pos, -1))
    nxt = np.minimum.accumulate(np.where(typ == 1, pos, len(idx))[::-1])[::-1]
    q = np.flatnonzero(typ == 0)
    b, a = last[q], nxt[q]
    b_ok = (b >= 0) & (k[idx[np.maximum(b, 0)]] == k[idx[q]])
    a_ok = (a < len(idx)) & (k[idx[np.minimum(a, len(idx) - 1)]] == k[idx[q]])
    return idx[q], np.where(b_ok, idx[np.maximum(b, 0)], -1), np.where(a_ok, idx[np.minimum(a, len(idx) - 1)], -1)


def coop_caps(fr):
    """The cooperation bound of every point (+inf: none) recomputed from docs/lanes.md's rule: in steps 1 ..
    n_steps - 1 (with lane changes), every merge-lane vehicle within its merge range of the lane's end (an MOBIL
    driver; not one that entered in that step: entries follow the cooperation) asks the vehicle right behind it in
    lane 1 (the last whose front is behind its own, not an entrant of that step); that vehicle, an MOBIL driver with
    coop_decel > 0, yields when its IDM behind the asker (gap x_asker - length_asker - x, its own speed, the asker's)
    is >= -coop_decel, and that acceleration bounds its own. Returns the bounds and the number of (asker, follower)
    pairs asked and yielding."""
    s = fr.setup
    n = len(fr.x)
    lc = [g["lc"] for g in s.groups]
    mob = np.array([m is not None for m in lc])[fr.gid]
    rng = np.array([m["merge_range_m"] if m else -1.0 for m in lc])[fr.gid]
    coop = np.array([m["coop_decel_mps2"] if m else 0.0 for m in lc])[fr.gid]
    live = (fr.k >= 1) & (fr.k < fr.n_steps) & ~fr.entrant
    askers = np.flatnonzero(live & (fr.lane == 0) & mob & (s.end_m - fr.x <= rng))
    cands = np.flatnonzero(live & (fr.lane == 1))
    cap = np.full(n, np.inf)
    if not len(askers):
        return cap, 0, 0
    i, fol, _ = behind_ahead(fr.k, fr.x, askers, cands)
    ok = fol >= 0
    i, fol = i[ok], fol[ok]
    asked = len(i)
    gap = fr.x[i] - fr.length[i] - fr.x[fol]
    ok = mob[fol] & (coop[fol] > 0.0) & (gap > 0.0)
    i, fol, gap = i[ok], fol[ok], gap[ok]
    a = per_group(s, fr.gid[fol], lambda g, m: idm(g["idm"], gap[m], fr.v[fol][m], fr.v[i][m]))
    y = a >= -coop[fol]
    np.minimum.at(cap, fol[y], a[y])
    return cap, asked, int(y.sum())


def with_cap(a, cap, dmax):
    """The engine's cap rule (docs/lanes.md, as a speed limit's): a > cap ? max(cap, -decel_max) : a."""
    return np.where(a > cap, np.maximum(cap, -dmax), a)


# ------------------------------------------------------------------------------------------------ 1. waves
def cycles_per_vehicle(serial, t, v, sel):
    """Stop-go cycles of each vehicle over its points in sel (time order): a fall below V_STOP, then a rise above
    V_GO. Returns the vehicles, their cycles, whether they stopped at all."""
    o = np.lexsort((t[sel], serial[sel]))
    s, vv = serial[sel][o], v[sel][o]
    first = np.concatenate([[True], s[1:] != s[:-1]])
    start = np.flatnonzero(first)
    n = np.zeros(len(start), dtype=np.int64)
    stopped = np.zeros(len(start), dtype=bool)
    ends = np.append(start[1:], len(s))
    for j, (lo, hi) in enumerate(zip(start, ends)):
        down = False
        for q in vv[lo:hi]:
            if not down and q < V_STOP:
                down = stopped[j] = True
            elif down and q > V_GO:
                down = False
                n[j] += 1
    return s[start], n, stopped


def wave_figures(path, x0, xm, xd, t0):
    f = h5py.File(path, "r")
    tr, tp = f["trajectories"], f["trips"]
    t, serial, x, v = tr["t"][()], tr["serial"][()], tr["x"][()], tr["v"][()]
    lane = tr["lane"][()].astype(np.int64)
    ent = dict(zip(tp["serial"][()].tolist(), tp["entry_time"][()].tolist()))
    late = np.array([ent[s] >= t0 for s in serial.tolist()])
    # main-lane vehicles (entered on a main lane: serial >= 2^40) after the warm-up, on the main lanes upstream
    up = (lane >= 1) & (serial >= LANE_KEY) & late & (x >= x0) & (x < xm)
    who, n, stopped = cycles_per_vehicle(serial, t, v, up)
    down = (lane >= 1) & (x >= xd) & (t >= t0)
    r = {"n": len(who), "slow": float(np.mean(v[up] < V_SLOW)), "two": float(np.mean(n >= 2)),
         "stopped": float(np.mean(stopped)), "two_if_stopped": float(np.mean(n[stopped] >= 2)) if stopped.any() else 0,
         "mean": float(n.mean()), "mean_if_stopped": float(n[stopped].mean()) if stopped.any() else 0.0,
         "any": int(np.sum(n > 0)), "up_min": float(v[up].min()), "down_min": float(v[down].min()),
         "down_mean": float(v[down].mean()), "merges": int(f["lanes/pair_changes"][()][0, 1])}
    assert r["n"] > 200, f"{path}: {r['n']} vehicles upstream"
    return r


def waves(high, low, x0, xm, xd, t0):
    x0, xm, xd, t0 = float(x0), float(xm), float(xd), float(t0)
    h, lo = wave_figures(high, x0, xm, xd, t0), wave_figures(low, x0, xm, xd, t0)
    acc = (f"high: {h['n']} vehicles upstream, {100 * h['slow']:.0f} % of their time below {V_SLOW:g} m/s, "
           f"{100 * h['stopped']:.0f} % stop, {100 * h['two']:.0f} % with >= 2 stop-go cycles ({100 * h['two_if_stopped']:.0f} % "
           f"of those that stop; {h['mean_if_stopped']:.1f} cycles on average), {h['merges']} merges, downstream "
           f"speeds >= {h['down_min']:.1f} m/s (mean {h['down_mean']:.1f}); low: {lo['n']} vehicles, "
           f"{lo['any']} with a cycle, upstream speeds >= {lo['up_min']:.1f} m/s, downstream >= {lo['down_min']:.1f} m/s")
    assert h["slow"] >= 0.4, "high demand: upstream not congested; " + acc
    assert h["two"] >= 0.3, "high demand: too few vehicles through >= 2 stop-go cycles; " + acc
    assert h["two_if_stopped"] >= 0.7, "high demand: stopped vehicles mostly stop once (a standing queue); " + acc
    assert lo["any"] == 0 and lo["up_min"] > V_FREE, "low demand: stops upstream; " + acc
    assert h["down_min"] > V_FREE and lo["down_min"] > V_FREE, "downstream of the merge not free; " + acc
    print(acc)


# ------------------------------------------------------------------------------------------------ 2. accelerations
def accel(path):
    fr = Frames(path)
    s = fr.setup
    assert all(g["noise"] == 0.0 for g in s.groups), "noise on: the accelerations cannot be recomputed"
    assert s.speed_limit is None and not s.zones, "a speed limit or zone: its cap is not recomputed here"
    steps = fr.k[fr.bounds[:-1]]
    sc = yaml.safe_load(fr.f["meta/scenario_text"][()].decode())
    assert float(sc["output"]["trajectory_interval_s"]) == float(sc["time"]["dt_s"]), "frames not every step"
    assert steps[-1] == fr.n_steps and len(steps) > fr.n_steps // 2, "frames missing"
    # the recorded accelerations are the ones applied: each vehicle's ballistic update to the next frame (where it
    # keeps moving; a vehicle that would reverse stops within the step)
    o = np.lexsort((fr.k, fr.serial))
    cont = (fr.serial[o][1:] == fr.serial[o][:-1]) & (fr.k[o][1:] == fr.k[o][:-1] + 1)
    xs, vs, as_ = fr.x[o], fr.v[o], fr.a[o]
    mv = cont & (vs[1:] > 0)
    e_v = np.abs(vs[1:] - vs[:-1] - as_[:-1] * fr.dt)[mv]
    e_x = np.abs(xs[1:] - xs[:-1] - vs[:-1] * fr.dt - 0.5 * as_[:-1] * fr.dt * fr.dt)[mv]
    assert e_v.max() < 1e-9 and e_x.max() < 1e-9, f"ballistic update off by {e_v.max():.3g} m/s, {e_x.max():.3g} m"
    own = own_lane_accel(fr)
    cap, asked, yielding = coop_caps(fr)
    dmax = np.array([g["dmax"] for g in s.groups])[fr.gid]
    want = with_cap(own, cap, dmax)
    err = np.abs(fr.a - want)
    bad = err > 1e-9
    if bad.any():
        j = np.flatnonzero(bad)[0]
        raise AssertionError(
            f"{int(bad.sum())} of {len(err)} accelerations differ (max {err.max():.3g} m/s^2); first: t = "
            f"{fr.k[j] * fr.dt:g} s, vehicle {int(fr.serial[j])} lane {fr.lane[j]} x = {fr.x[j]:.3f}: recorded "
            f"{fr.a[j]!r}, own-lane IDM {own[j]!r}, cooperation bound {cap[j]!r}; {int(np.sum(bad & np.isfinite(cap)))} "
            f"of the differing ones have a bound, {int(np.sum(bad & ~np.isfinite(cap)))} none")
    binds = np.isfinite(cap) & (own > cap)
    steps_b = len(np.unique(fr.k[binds]))
    assert binds.sum() >= 200 and steps_b >= 100, f"only {int(binds.sum())} binding yields in {steps_b} steps"
    print(f"{len(err)} accelerations in {len(steps)} frames (each the one of the vehicle's ballistic update to the "
          f"next frame, {int(mv.sum())} checked) equal own-lane IDM or its cooperation bound (max |diff| "
          f"{err.max():.2g} m/s^2, none excluded); {asked} asker/follower pairs asked, {yielding} yielding, "
          f"{int(binds.sum())} yields that bind (below own-lane IDM by up to {np.max((own - cap)[binds]):.2f} m/s^2) "
          f"in {steps_b} steps, by {len(np.unique(fr.serial[binds]))} vehicles; {int(np.sum(np.isfinite(cap) & ~binds))} "
          f"bounds above their vehicle's own-lane IDM")


# ------------------------------------------------------------------------------------------------ 2b. mandatory
def mandatory(path):
    """MOBIL's mandatory rule (docs/lanes.md): at step k (1 <= k < n_steps), from the state at the step's start
    (frame k's positions and speeds, frame k-1's lanes; not the step's entrants), a merge-lane vehicle within its
    merge range of the lane's end changes into lane 1 when the gap is safe with b_mandatory: the gap to its new
    leader (first at or ahead of it) and its new follower's (last behind it) positive, its IDM behind the new leader
    (or a free road) and the new follower's IDM behind it >= -b_mandatory (and b_mandatory + its own > 0: MOBIL's
    advantage). One vehicle per gap and step: a vehicle that qualifies and stays is excused only when another
    vehicle entered that gap of lane 1 at that step."""
    fr = Frames(path)
    s = fr.setup
    # frame k-1's lane of each point of frame k (vehicles present in both frames)
    o = np.lexsort((fr.k, fr.serial))
    cont = (fr.serial[o][1:] == fr.serial[o][:-1]) & (fr.k[o][1:] == fr.k[o][:-1] + 1)
    prev = np.full(len(fr.x), -1)
    prev[o[1:][cont]] = fr.lane[o[:-1][cont]]
    live = (fr.k >= 1) & (fr.k < fr.n_steps) & ~fr.entrant
    assert np.all(prev[live] >= 0), "a vehicle on the road missing from the previous frame"
    changed = live & (prev != fr.lane)
    lc = [g["lc"] for g in s.groups]
    mob = np.array([m is not None for m in lc])[fr.gid]
    rng = np.array([m["merge_range_m"] if m else -1.0 for m in lc])[fr.gid]
    bm = np.array([m["b_mandatory_mps2"] if m else 0.0 for m in lc])[fr.gid]
    ramp = live & (prev == 0)
    askers = np.flatnonzero(ramp & mob & (s.end_m - fr.x <= rng))
    cands = np.flatnonzero(live & (prev == 1))
    i, fo, ld = behind_ahead(fr.k, fr.x, askers, cands)
    x, v, L = fr.x, fr.v, fr.length
    has_ld, has_fo = ld >= 0, fo >= 0
    ldi, foi = np.where(has_ld, ld, 0), np.where(has_fo, fo, 0)
    gap_new = np.where(has_ld, x[ldi] - L[ldi] - x[i], FREE_GAP_M)
    vl_new = np.where(has_ld, v[ldi], v[i])
    gap_fo = np.where(has_fo, x[i] - L[i] - x[foi], 1.0)
    own_new = per_group(s, fr.gid[i], lambda g, m: idm(g["idm"], gap_new[m], v[i][m], vl_new[m]))
    fo_new = np.where(has_fo, per_group(s, fr.gid[foi], lambda g, m: idm(g["idm"], gap_fo[m], v[foi][m], v[i][m])),
                      0.0)
    b = bm[i]
    want = (gap_new > 0) & (gap_fo > 0) & (own_new >= -b) & (fo_new >= -b) & (b + own_new > 0)
    # decisions within 1e-9 m/s^2 of a bound are not judged (rounding)
    edge = (np.abs(own_new + b) < 1e-9) | (has_fo & (np.abs(fo_new + b) < 1e-9))
    went = changed[i]
    assert np.all(fr.lane[i][went] == 1), "a merge-lane vehicle went elsewhere than lane 1"
    wrong = went & ~want & ~edge
    assert not wrong.any(), (f"{int(wrong.sum())} merges MOBIL's mandatory rule does not allow; first: t = "
                             f"{fr.k[i][wrong][0] * fr.dt:g} s x = {x[i][wrong][0]:.2f}, own {own_new[wrong][0]:.3f}, "
                             f"new follower {fo_new[wrong][0]:.3f} m/s^2")
    stay = want & ~went & ~edge
    # another vehicle entered the same gap of lane 1 in that step: a changer into lane 1 between the gap's follower
    # and leader
    into1 = np.flatnonzero(changed & (fr.lane == 1))
    excused = np.zeros(len(i), dtype=bool)
    for q in np.flatnonzero(stay):
        kk = fr.k[i[q]]
        lo = x[fo[q]] if has_fo[q] else -np.inf
        hi = x[ld[q]] if has_ld[q] else np.inf
        c = into1[fr.k[into1] == kk]
        excused[q] = np.any((x[c] > lo) & (x[c] <= hi) & (c != i[q]))
    missed = stay & ~excused
    assert not missed.any(), (f"{int(missed.sum())} merge-lane vehicles with a gap the mandatory rule accepts stayed; "
                              f"first: t = {fr.k[i][missed][0] * fr.dt:g} s, x = {x[i][missed][0]:.2f} m, v = "
                              f"{v[i][missed][0]:.2f} m/s, own {own_new[missed][0]:.3f}, new follower "
                              f"{fo_new[missed][0]:.3f} m/s^2")
    merges = int(went.sum())
    assert merges >= 50, f"only {merges} merges"
    print(f"{len(i)} merge-lane vehicle-steps within the merge range judged: {merges} merges, each allowed by the "
          f"mandatory rule; {int(want.sum())} safe gaps, {int((stay & excused).sum())} of them taken in that step by "
          f"another vehicle, {int(edge.sum())} within 1e-9 of a bound; the hardest braking accepted by a merger "
          f"{np.min(own_new[went]):.2f}, imposed on a new follower {np.min(np.where(has_fo, fo_new, 0)[went]):.2f} m/s^2")


# ------------------------------------------------------------------------------------------------ 3. coop on/off
def coop_figures(path, x0, xm, t0):
    f = h5py.File(path, "r")
    tr, tp, la = f["trajectories"], f["trips"], f["lanes"]
    t, x, v = tr["t"][()], tr["x"][()], tr["v"][()]
    lane = tr["lane"][()].astype(np.int64)
    up = (lane >= 1) & (x >= x0) & (x < xm) & (t >= t0)
    lt = la["t"][()]
    return {"merges": int(la["pair_changes"][()][0, 1]),
            "queue": float(la["vehicles"][()][lt >= t0, 0].mean()),
            "ramp_in": int(np.sum(tp["serial"][()] < LANE_KEY)),
            "slow": float(np.mean(v[up] < V_SLOW)), "up_mean": float(v[up].mean())}


def coop_effect(on, off, x0, xm, t0):
    a, b = coop_figures(on, float(x0), float(xm), float(t0)), coop_figures(off, float(x0), float(xm), float(t0))
    acc = (f"on / off: {a['merges']} / {b['merges']} merges, {a['ramp_in']} / {b['ramp_in']} ramp vehicles entered, "
           f"{a['queue']:.1f} / {b['queue']:.1f} vehicles in the merge lane on average, main lanes upstream "
           f"{100 * a['slow']:.0f} / {100 * b['slow']:.0f} % of the time below {V_SLOW:g} m/s (mean "
           f"{a['up_mean']:.1f} / {b['up_mean']:.1f} m/s)")
    assert a["merges"] >= 2 * b["merges"], "cooperation does not double the merges: " + acc
    assert b["queue"] >= a["queue"] + 3, "without cooperation the merge lane is not fuller: " + acc
    assert a["ramp_in"] >= 1.5 * b["ramp_in"], "without cooperation the ramp's entrance is not slower: " + acc
    assert b["slow"] <= 0.2 and a["slow"] >= 0.4, "the congestion is not where it should be: " + acc
    print(acc)


# ------------------------------------------------------------------------------------------------ 4. conservation
def conservation(path):
    """tests/corridor_lanes_check.py's `physical` method (frames every step against /trips and /lanes), with the
    ramp's vehicles entering at start_m (`physical` itself takes every vehicle to enter at x = 0, which its detector
    and Edie checks rely on), then each lane's balance at every step and the merge lane's own rules."""
    fr = Frames(path)
    s, f = fr.setup, fr.f
    tp = f["trips"]
    n_lanes, ns, dt = s.n_lanes, fr.n_steps, fr.dt
    x, lane, k = fr.x, fr.lane, fr.k
    L_road = float(f["meta/road_length"][()])
    steps = k[fr.bounds[:-1]]
    assert steps[-1] == ns and len(steps) > ns // 2 and np.all(np.diff(steps) >= 1), "frames every step"
    # every frame: each lane front first with positive gaps; the merge lane's front behind its end
    same = fr.has_leader[1:]
    gap = x[:-1] - fr.length[:-1] - x[1:]
    assert np.all(gap[same] > 0), f"gap {gap[same].min():g} m"
    assert np.all((x >= 0) & (x < L_road)), "a point off the road"
    # frame k holds exactly the vehicles entered at or before k and not exited by then (exits: at the end of a
    # step, so exit step = exit_time / dt is the first frame without the vehicle)
    ent = fr.entry_step
    done = tp["completed"][()] == 1
    exs = np.full(len(ent), np.iinfo(np.int64).max)
    exs[done] = step_of(tp["exit_time"][()][done], dt)
    assert np.all((ent[fr.row] <= k) & (k < exs[fr.row])), "a point of a vehicle not on the road"
    pair = np.lexsort((fr.serial, k))
    dup = (k[pair][1:] == k[pair][:-1]) & (fr.serial[pair][1:] == fr.serial[pair][:-1])
    assert not dup.any(), "a vehicle twice in a frame"
    on = np.zeros(ns + 2, dtype=np.int64)
    np.add.at(on, ent, 1)
    np.add.at(on, np.minimum(exs, ns + 1), -1)
    on = np.cumsum(on)[:ns + 1]
    got = np.bincount(k, minlength=ns + 1)
    bad = np.flatnonzero(got != on)
    assert not len(bad), f"t = {bad[0] * dt:g} s: {got[bad[0]]} on the road, /trips says {on[bad[0]]}"
    ts = f["timeseries"]
    assert np.array_equal(ts["vehicles"][()], on[step_of(ts["t"][()], dt)]), "timeseries/vehicles"
    # each lane's vehicles at every step, from the frames, against entries (trips: entry step, the lane of the
    # serial's key), exits (trips: exit step, lane) and the changes between consecutive frames
    cnt = np.zeros((ns + 1, n_lanes), dtype=np.int64)
    np.add.at(cnt, (k, lane), 1)
    e_lane = (tp["serial"][()] // LANE_KEY).astype(np.int64)
    ein = np.zeros((ns + 1, n_lanes), dtype=np.int64)
    np.add.at(ein, (ent, e_lane), 1)
    ex = np.zeros((ns + 2, n_lanes), dtype=np.int64)
    np.add.at(ex, (exs[done], tp["lane"][()][done].astype(np.int64)), 1)
    o = np.lexsort((k, fr.serial))
    cont = fr.serial[o][1:] == fr.serial[o][:-1]
    assert np.all(k[o][1:][cont] == k[o][:-1][cont] + 1), "a vehicle missing from a frame"
    chg = cont & (lane[o][1:] != lane[o][:-1])
    src, dst, when = lane[o][:-1][chg], lane[o][1:][chg], k[o][1:][chg]
    assert np.all(np.abs(dst - src) == 1), "a change of more than one lane"
    cin = np.zeros((ns + 1, n_lanes), dtype=np.int64)
    cout = np.zeros((ns + 1, n_lanes), dtype=np.int64)
    np.add.at(cin, (when, dst), 1)
    np.add.at(cout, (when, src), 1)
    bal = np.cumsum(ein - ex[:ns + 1] + cin - cout, axis=0)
    bad = np.argwhere(bal != cnt)
    assert not len(bad), f"t = {bad[0][0] * dt:g} s lane {bad[0][1]}: {cnt[tuple(bad[0])]} on the lane, entries - " \
                         f"exits + changes in - out = {bal[tuple(bad[0])]}"
    who = fr.row[o][1:][chg]
    assert np.array_equal(np.bincount(who, minlength=len(ent)), tp["lane_changes"][()].astype(np.int64)), \
        "/trips/lane_changes differ from the frames"
    # the merge lane: its vehicles enter at start_m, stay within [start, end], leave only into lane 1; no one enters
    # it by a change and no one exits from it
    fp = o[np.concatenate([[True], ~cont])]
    assert np.all(lane[fp] == (fr.serial[fp] // LANE_KEY).astype(np.int64)), "a vehicle's first point off its lane"
    assert np.all(x[fp][lane[fp] == 0] == s.start_m), "a ramp vehicle entered elsewhere than start_m"
    assert np.all(x[fp][lane[fp] > 0] == 0.0), "a main-lane vehicle entered elsewhere than x = 0"
    on0 = lane == 0
    assert np.all((x[on0] >= s.start_m) & (x[on0] <= s.end_m)), "a point of the merge lane off the ramp"
    assert not np.any(dst == 0), "a change into the merge lane"
    assert np.all(fr.serial[o][1:][chg][src == 0] < LANE_KEY), "a main-lane vehicle left the merge lane"
    assert ex[:, 0].sum() == 0, "an exit from the merge lane"
    # the records: /lanes/vehicles, lane_changes per record, pair_changes; the ramp's balance
    la = f["lanes"]
    rk = step_of(la["t"][()], dt)
    assert np.array_equal(la["vehicles"][()], cnt[rk].astype(float)), "/lanes/vehicles differ from the balance"
    per = np.array([np.sum((when > lo) & (when <= hi)) for lo, hi in zip(np.concatenate([[-1], rk[:-1]]), rk)])
    assert np.array_equal(per, la["lane_changes"][()]), "/lanes/lane_changes differ from the frames"
    pm = np.zeros((n_lanes, n_lanes), dtype=np.int64)
    np.add.at(pm, (src, dst), 1)
    assert np.array_equal(pm, la["pair_changes"][()]), f"/lanes/pair_changes {la['pair_changes'][()].tolist()}, " \
                                                       f"seen {pm.tolist()}"
    merged, ramp_in = np.cumsum(cout[:, 0]), np.cumsum(ein[:, 0])
    assert np.array_equal(cnt[:, 0], ramp_in - merged), "merge lane != ramp entries - merges"
    # detectors and Edie's distance: a vehicle drives from its entry point (0 or start_m) to L or its last point
    x_in = np.where(e_lane == 0, s.start_m, 0.0)
    last_x = np.full(len(ent), np.nan)
    lp = o[np.concatenate([~cont, [True]])]
    last_x[fr.row[lp]] = x[lp]
    x_out = np.where(done, L_road, last_x)
    assert np.all(np.isfinite(x_out)), "an unfinished trip without points"
    det = f["detectors"]
    for j, xd in enumerate(det["x"][()]):
        want = int(np.sum((x_in <= xd) & (xd < x_out)))
        assert int(det["count"][()][:, j].sum()) == want, f"detector at {xd:g} m: {det['count'][()][:, j].sum()}, " \
                                                          f"{want} passed it"
    d_want = float(np.sum(x_out - x_in))
    d_edie = float(f["edie/distance"][()].sum())
    assert abs(d_edie - d_want) <= 1e-9 * d_want, f"Edie distance {d_edie} m, the trips drove {d_want} m"
    print(f"{ns + 1} steps, {len(x)} points: each lane front first with positive gaps, the vehicles on the road "
          f"those /trips says; each lane's vehicles at every step = entries - exits + changes in - out ({len(src)} "
          f"changes, pairs {pm.tolist()}, /trips, /lanes alike); ramp: {ramp_in[-1]} entered at {s.start_m:g} m, "
          f"{merged[-1]} merged into lane 1, {cnt[-1, 0]} left in the merge lane (up to {cnt[:, 0].max()}); "
          f"/lanes/vehicles equal at {len(rk)} records; {len(det['x'])} detectors and Edie's distance from /trips")


# ------------------------------------------------------------------------------------------------ 5. yields
def yields(path, min_lane_n, min_yields):
    """Frames of a run with noise: a point whose recorded acceleration equals (to 1e-12 relative) the cooperation
    bound recomputed for it is a binding yield (noise draws do not land on that value)."""
    fr = Frames(path)
    cap, asked, yielding = coop_caps(fr)
    hit = np.isfinite(cap) & (np.abs(fr.a - cap) <= 1e-12 * np.maximum(1.0, np.abs(cap)))
    # the lane's vehicles in the frame of each hit
    key = fr.k * 16 + fr.lane
    uk, inv, nper = np.unique(key, return_inverse=True, return_counts=True)
    big = hit & (nper[inv] > int(min_lane_n))
    acc = (f"{len(np.unique(fr.k))} frames: {asked} asker/follower pairs, {yielding} yielding, {int(hit.sum())} "
           f"accelerations equal to their cooperation bound, {int(big.sum())} of them in a lane of more than "
           f"{min_lane_n} vehicles (up to {nper.max()}), {int(fr.f['summary/lane_changes'][()])} lane changes, "
           f"{int(fr.f['lanes/pair_changes'][()][0, 1])} merges")
    assert big.sum() >= int(min_yields), acc
    print(acc)


if __name__ == "__main__":
    cmd, args = sys.argv[1], sys.argv[2:]
    try:
        {"waves": waves, "accel": accel, "mandatory": mandatory, "coop_effect": coop_effect,
         "conservation": conservation, "yields": yields}[cmd](*args)
    except AssertionError as e:
        print(f"{cmd}: {e}")
        sys.exit(1)
