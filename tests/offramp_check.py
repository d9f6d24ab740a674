"""Checks of corridor results with an off-ramp (corridor.off_ramp) for tests/t_offramp.sh, one subcommand per check;
each exits non-zero with the reason on failure and prints a one-line account of what it measured on success.

  conserve FILE.h5               vehicles conserved at every record and at the end, from /trips alone: entered =
                                 exited at x = L + off-ramp exits + on the road; /summary's counters, trip count and
                                 trip means (completed = 1 only) from the /trips rows
  frames FILE.h5 [MIN_WIDE]      trajectories written every step: every vehicle in every frame from its entry to its
                                 exit, the ballistic update across frames; who is bound for the off-ramp recomputed
                                 from the seed (Philox4x32-10 written here from its published definition, the key
                                 layout of src/core/rng.c), and each one's fate from the frames: leaves at the end of
                                 the step in which its front reaches at_m in the exit lane (the /trips row, lane,
                                 exit time and distance), misses it in another lane (counted in
                                 /summary/missed_exits) and drives on to L; nobody else leaves before L; on the
                                 approach a bound vehicle changes lanes only toward the exit lane, and takes at
                                 once any wide gap in the lane toward it (at least MIN_WIDE such gaps)
  share FILE.h5                  the share of the vehicles that reached at_m (entered upstream) which were bound for
                                 the off-ramp (off-ramp exits + missed exits), within 4 binomial standard deviations
  all_leave FILE.h5              share 1 on one lane: every vehicle leaves at at_m, none reaches L
  zero_equals A.h5 B.h5          A (share 0) equals B (no off-ramp) bit for bit: every dataset and attribute but the
                                 off-ramp's two counters (0) and the scenario text
  ahead A.h5 ZERO.h5             one lane, no randomness on the road: each vehicle's trajectory equals the share-0
                                 run's, bit for bit, until a vehicle ahead of it leaves by the off-ramp (it cannot see
                                 any other difference): whole trips for the vehicles ahead of the first exit
  merge A.h5 ZERO.h5             with an on-ramp, frames every step: a vehicle bound for the off-ramp in the merge
                                 lane on the approach takes at once a wide gap of lane 1 beside it, and no vehicle
                                 stays in the merge lane much longer than in the run with share 0
  coop A.h5 NONE.h5              A against the same run where nobody yields (coop_decel_mps2: 0), frames every step:
                                 where they first differ, only accelerations differ, each one lowered, of the
                                 vehicle right behind a vehicle bound for the off-ramp on its approach in the lane
                                 beside it away from the exit lane (it asked that one to let it in)
  identical A.h5 B.h5 MIN_N      every dataset and attribute equal bit for bit (wall times and threads left out),
                                 with off-ramp exits, missed exits and more than MIN_N vehicles in some lane
  interrupted PARTIAL.h5         the stopped run's trips so far include off-ramp exits (prints "STEPS EXITS")
"""
import sys

import h5py
import numpy as np
import yaml  # python3-yaml (Debian): the scenario text a result stores is plain YAML

LANE_KEY = 2 ** 40  # a corridor's lane l numbers its vehicles from l 2^40 (docs/lanes.md, "Random keys")
RNG_USER = 16       # include/wavefuel/rng.h: WF_RNG_USER
RNG_EXIT = RNG_USER + 34  # include/wavefuel/corridor.h: WF_RNG_CORRIDOR_EXIT


# ------------------------------------------------------------------ Philox4x32-10 (Salmon et al., SC'11)
M0, M1, W0, W1 = 0xD2511F53, 0xCD9E8D57, 0x9E3779B9, 0xBB67AE85
U32 = np.uint64(0xFFFFFFFF)


def philox4x32_10(ctr, key):
    """Ten rounds on uint64 arrays holding 32-bit words; the key is bumped between rounds."""
    c = [np.asarray(w, dtype=np.uint64) & U32 for w in ctr]
    k0, k1 = np.uint64(key[0]) & U32, np.uint64(key[1]) & U32
    for r in range(10):
        if r:
            k0, k1 = (k0 + np.uint64(W0)) & U32, (k1 + np.uint64(W1)) & U32
        p0, p1 = c[0] * np.uint64(M0), c[2] * np.uint64(M1)  # 32 x 32 bits: exact in 64
        c = [(p1 >> np.uint64(32)) ^ c[1] ^ k0, p1 & U32, (p0 >> np.uint64(32)) ^ c[3] ^ k1, p0 & U32]
    return c


# The known-answer vectors of Random123 (kat_vectors: philox4x32 10 rounds)
_KAT = [(([0, 0, 0, 0], [0, 0]), [0x6627E8D5, 0xE169C58D, 0xBC57AC4C, 0x9B00DBD8]),
        (([0x243F6A88, 0x85A308D3, 0x13198A2E, 0x03707344], [0xA4093822, 0x299F31D0]),
         [0xD16CFE09, 0x94FDCCEB, 0x5001E420, 0x24126EA1])]
for (_c, _k), _want in _KAT:
    assert [int(w) for w in philox4x32_10(_c, _k)] == _want, "Philox4x32-10 fails its known-answer test"


def uniform0(seed, stream, a):
    """The first of the two uniforms of (seed, stream, a, b = 0): counter (a, b, stream ^ (a >> 32) * golden, b >> 32),
    key (seed low, seed high); ((w >> 11) + 0.5) 2^-53 of the first 64-bit word w of the output."""
    a = np.asarray(a, dtype=np.uint64)
    zero = np.zeros_like(a)
    s = np.uint64(stream) ^ (((a >> np.uint64(32)) * np.uint64(0x9E3779B9)) & U32)
    r = philox4x32_10([a & U32, zero, s, zero], [seed & 0xFFFFFFFF, seed >> 32])
    x = (r[0] << np.uint64(32)) | r[1]
    return ((x >> np.uint64(11)).astype(np.float64) + 0.5) * 2.0 ** -53


# ------------------------------------------------------------------ helpers
def raw(x):
    x = np.asarray(x)
    return (x.dtype.str, x.shape, x.tobytes()) if x.dtype.kind in "fiub" else (x.shape, x.tolist())


def step_of(t, dt):
    """Step index of times written as k dt."""
    t = np.asarray(t, dtype=float)
    k = np.rint(t / dt)
    assert np.all(np.abs(k * dt - t) <= 1e-9 * np.maximum(1.0, np.abs(t))), "times off the step grid"
    return k.astype(np.int64)


def setup(f):
    """The run's off-ramp and road from the stored scenario text and overrides."""
    sc = yaml.safe_load(f["meta/scenario_text"][()].decode())
    for line in f["meta/overrides"][()].decode().splitlines():
        if not line.strip():
            continue
        key, val = line.split("=", 1)
        node, parts = sc, key.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = yaml.safe_load(val)
    corr = sc.get("corridor", {})
    off = corr.get("off_ramp")
    ramp = corr.get("on_ramp")
    lanes = int(sc["road"].get("lanes", 1)) + (1 if ramp else 0)
    p = {"sc": sc, "seed": int(f["meta/seed"][()]), "drops": corr.get("lane_drops") or [],
         "L": float(f["meta/road_length"][()]), "dt": float(f["meta/dt"][()]), "steps": int(f["meta/steps_done"][()]),
         "lanes": lanes, "ramp": ramp, "off": off is not None, "exit_lane": 1 if ramp else 0}
    if off is not None:
        p.update(at=float(off["at_m"]), share=float(off["share"]), approach=float(off.get("approach_m", 1000.0)))
    return p


def name(serial):
    """A corridor vehicle as lane:number (its serial is lane 2^40 + number)."""
    return f"{int(serial) // LANE_KEY}:{int(serial) % LANE_KEY}"


def entry_x(p, serial):
    """Where each vehicle entered: the merge lane's (lane 0's, with an on-ramp) at its start, the others at 0."""
    serial = np.asarray(serial, dtype=np.float64)
    if p["ramp"]:
        return np.where(serial < LANE_KEY, float(p["ramp"]["start_m"]), 0.0)
    return np.zeros(len(serial))


def bound_for(p, serial):
    """Whether each vehicle is bound for the off-ramp: it entered upstream of it and its draw is below the share."""
    u = uniform0(p["seed"], RNG_EXIT, np.asarray(serial, dtype=np.float64).astype(np.uint64))
    return (entry_x(p, serial) < p["at"]) & (u < p["share"])


def ballistic(x, v, a, dt):
    """Where the step from (x, v, a) ends (src/integ/ballistic.c: a vehicle that would reverse stops)."""
    vn = v + a * dt
    run = x + (v * dt + 0.5 * a * dt * dt)
    stop = x + (-(v * v) / (2.0 * np.where(a < 0.0, a, -1.0)))
    return np.where(vn >= 0.0, run, stop)


# ------------------------------------------------------------------ checks
def conserve(path):
    f = h5py.File(path, "r")
    p = setup(f)
    tp, sm, ts = f["trips"], f["summary"], f["timeseries"]
    c = tp["completed"][()]
    serial = tp["serial"][()]
    assert len(np.unique(serial)) == len(serial), "a vehicle with two /trips rows"
    assert set(np.unique(c).tolist()) <= {0.0, 1.0, 2.0}, f"completed values {np.unique(c)}"
    n0, n1, n2 = (int(np.sum(c == q)) for q in (0, 1, 2))
    S = {k: int(sm[k][()]) for k in ("entered", "exited", "on_road", "trips", "arrived", "queued", "off_ramp_exits",
                                     "missed_exits")}
    want = {"entered": n0 + n1 + n2, "exited": n1, "on_road": n0, "trips": n1, "off_ramp_exits": n2,
            "arrived": S["entered"] + S["queued"]}
    bad = {k: (S[k], w) for k, w in want.items() if S[k] != w}
    assert not bad, f"/summary (got, from /trips): {bad}"
    assert S["entered"] == S["exited"] + S["off_ramp_exits"] + S["on_road"], f"end: {S}"
    assert 0 <= S["missed_exits"] <= n1 + n0, f"missed_exits {S['missed_exits']}"
    # trip means over the trips that reached L only
    one = c == 1
    if n1:
        for k, col in (("mean_travel_time", "travel_time"), ("mean_trip_fuel", "fuel")):
            got, w = float(sm[k][()]), float(np.mean(tp[col][()][one]))
            assert abs(got - w) <= 1e-9 * abs(w), f"/summary/{k} {got!r}, trips with completed 1: {w!r}"
    ncls = len(sm["class_trips"][()])
    assert np.array_equal(sm["class_trips"][()].astype(np.int64),
                          np.bincount(tp["class_id"][()][one].astype(np.int64), minlength=ncls)), "class_trips"
    assert np.array_equal(sm["class_entered"][()].astype(np.int64),
                          np.bincount(tp["class_id"][()].astype(np.int64), minlength=ncls)), "class_entered"
    assert np.all(np.isnan(tp["exit_time"][()][c == 0])) and np.all(np.isfinite(tp["exit_time"][()][c > 0])), \
        "exit_time NaN exactly when not completed"
    # every record: what /trips says had entered, left at L, left by the off-ramp by then
    dt = p["dt"]
    rk = step_of(ts["t"][()], dt)
    ent = np.sort(step_of(tp["entry_time"][()], dt))
    ex1 = np.sort(step_of(tp["exit_time"][()][c == 1], dt))
    ex2 = np.sort(step_of(tp["exit_time"][()][c == 2], dt))
    e_in = np.searchsorted(ent, rk, side="right")
    e_1 = np.searchsorted(ex1, rk, side="right")
    e_2 = np.searchsorted(ex2, rk, side="right")
    for k, w in (("entered", e_in), ("exited", e_1), ("vehicles", e_in - e_1 - e_2)):
        got = ts[k][()].astype(np.int64)
        assert np.array_equal(got, w), (f"/timeseries/{k} differs from /trips at {int(np.sum(got != w))} records, "
                                        f"first t = {ts['t'][()][np.argmax(got != w)]:g} s: {got[got != w][0]} vs "
                                        f"{w[got != w][0]}")
    off_rec = ts["entered"][()] - ts["exited"][()] - ts["vehicles"][()]
    assert np.all(np.diff(off_rec) >= 0), "off-ramp exits implied by the records decrease"
    assert rk[-1] == p["steps"] and off_rec[-1] == S["off_ramp_exits"], "the last record"
    tail = ""
    if "trajectories" in f:
        tk = step_of(f["trajectories/t"][()], dt)
        if tk[-1] == p["steps"]:
            assert int(np.sum(tk == tk[-1])) == n0, "the final frame does not hold the vehicles on the road"
            tail = ", final frame alike"
    print(f"{len(rk)} records and the end: {S['entered']} entered = {n1} at L + {n2} by the off-ramp + {n0} on the "
          f"road; {S['missed_exits']} missed; /summary counters, trip means, classes from /trips{tail}")


def frames(path, min_wide=0):
    f = h5py.File(path, "r")
    p = setup(f)
    dt, L, at, ex_lane = p["dt"], p["L"], p["at"], p["exit_lane"]
    tr, tp = f["trajectories"], f["trips"]
    k = step_of(tr["t"][()], dt)
    assert np.all(np.diff(k) >= 0), "frames out of order"
    assert k[-1] == p["steps"], "no frame at the final instant"
    serial = tr["serial"][()]
    x, v, a = tr["x"][()], tr["v"][()], tr["a"][()]
    lane = tr["lane"][()].astype(np.int64) if "lane" in tr else np.zeros(len(x), dtype=np.int64)
    ts = tp["serial"][()]
    so = np.argsort(ts)
    row = so[np.searchsorted(ts[so], serial)]
    assert np.array_equal(ts[row], serial), "a trajectory point's vehicle has no trip"
    n = len(ts)
    c = tp["completed"][()].astype(np.int64)
    t_lane = tp["lane"][()].astype(np.int64) if "lane" in tp else np.zeros(n, dtype=np.int64)
    ent = step_of(tp["entry_time"][()], dt)
    exk = np.full(n, -1, dtype=np.int64)
    exk[c > 0] = step_of(tp["exit_time"][()][c > 0], dt)
    x0 = entry_x(p, ts)
    # each vehicle's points in step order; consecutive steps, from its entry to the step before its exit
    o = np.lexsort((k, row))
    ro, ko = row[o], k[o]
    same = ro[1:] == ro[:-1]
    assert np.all(np.diff(ko)[same] == 1), "a vehicle missing from a frame"
    first = np.flatnonzero(np.concatenate([[True], ~same]))
    last = np.flatnonzero(np.concatenate([~same, [True]]))
    who = ro[first]
    assert len(who) == n, f"{n - len(who)} entered vehicles never in a frame"
    assert np.array_equal(ko[first], ent[who]), "a vehicle's first frame is not its entry step"
    assert np.array_equal(x[o][first], x0[who]), "a vehicle's first point is not its entrance"
    want_last = np.where(c[who] > 0, exk[who] - 1, p["steps"])
    bad = ko[last] != want_last
    assert not bad.any(), (f"{int(bad.sum())} vehicles' last frames do not fit /trips: vehicle {name(ts[who][bad][0])} "
                           f"completed {c[who][bad][0]}, last frame step {ko[last][bad][0]}, want {want_last[bad][0]}")
    # the ballistic update, frame to frame (every later point from the one before) and past the last frame
    xo, vo, ao, lo = x[o], v[o], a[o], lane[o]
    nxt = ballistic(xo, vo, ao, dt)
    err = np.abs(nxt[:-1][same] - xo[1:][same])
    assert int(f["summary/overlaps"][()]) == 0, "overlap repairs"
    assert err.max() <= 1e-9 * L, f"ballistic update off by {err.max():g} m"
    x_end = nxt[last]                      # where each vehicle's front is after its last step
    dist = tp["distance"][()][who]
    dfit = np.abs(dist - (np.where(c[who] > 0, x_end, xo[last]) - x0[who]))
    assert dfit.max() <= 1e-9 * L, f"/trips/distance differs from the frames by {dfit.max():g} m"
    step_travel = vo[last] * dt + 0.5 * np.maximum(ao[last], 0.0) * dt * dt + 1e-9 * L
    assert np.all(xo < L), "a point at or beyond L"
    # who is bound, and the step in which each vehicle's front reaches at_m (frame j: x_j < at <= the next)
    b = bound_for(p, ts)
    cross_pt = np.flatnonzero((xo < at) & (nxt >= at) & (ko < p["steps"]))  # no step after the final instant
    cross_row = ro[cross_pt]
    assert len(np.unique(cross_row)) == len(cross_row), "a vehicle reaching at_m twice"
    crossed = np.zeros(n, dtype=bool)
    crossed[cross_row] = True
    cross_lane = np.full(n, -1)
    cross_lane[cross_row] = lo[cross_pt]
    cross_k = np.full(n, -1)
    cross_k[cross_row] = ko[cross_pt]
    upstream = x0 < at
    assert np.all(crossed[c > 0] | ~upstream[c > 0]), "a vehicle completed without reaching at_m"
    take = b & crossed & (cross_lane == ex_lane)
    miss = b & crossed & (cross_lane != ex_lane)
    # those who take it leave at the end of that step from the exit lane; nobody else leaves before L
    assert np.array_equal(np.flatnonzero(c == 2), np.flatnonzero(take)), (
        f"left by the off-ramp: {int(np.sum(c == 2))}; bound and at at_m in lane {ex_lane}: {int(take.sum())}; "
        f"first differing vehicle {name(ts[np.flatnonzero((c == 2) != take)[0]])}")
    assert np.all(exk[take] == cross_k[take] + 1), "an off-ramp exit not at the end of the step that reached at_m"
    assert np.all(t_lane[take] == ex_lane), f"/trips/lane of an off-ramp exit is not the exit lane {ex_lane}"
    pos = np.empty(n, dtype=np.int64)     # each /trips row's vehicle among first / last
    pos[who] = np.arange(n)
    assert np.all(lo[last][pos[take]] == ex_lane), "an off-ramp exit whose last frame is not in the exit lane"
    over = dist[pos[take]] - (at - x0[take])
    assert np.all(over >= -1e-9 * L) and np.all(over <= step_travel[pos[take]]), (
        f"off-ramp exits' distances: at_m - entry + [{over.min():g}, {over.max():g}] m, beyond one step's travel")
    one = c == 1
    assert np.all(x_end[pos[one]] >= L), "a trip completed before its front reached L"
    over1 = dist[pos[one]] - (L - x0[one])
    assert np.all(over1 >= -1e-9 * L) and np.all(over1 <= step_travel[pos[one]]), "trips at L: distance"
    # the missed: counted, drive on (nobody bound and missed is removed) to L
    n_miss = int(f["summary/missed_exits"][()])
    assert n_miss == int(miss.sum()), f"/summary/missed_exits {n_miss}, bound and at at_m in another lane: {miss.sum()}"
    assert np.all(c[miss] != 2) and np.all(ko[last][pos[miss]] > cross_k[miss]), "a missed exit left the road"
    # on the approach a bound vehicle changes only toward the exit lane (judged where it decides: its position at
    # the start of the step, which the change keeps)
    chg = same & (lo[1:] != lo[:-1])
    ci = np.flatnonzero(chg) + 1           # the point after each change
    on_appr = b[ro[ci]] & (xo[ci] >= at - p["approach"]) & (xo[ci] < at)
    toward = np.abs(lo[ci] - ex_lane) < np.abs(lo[ci - 1] - ex_lane)
    wrong = on_appr & ~toward
    assert not wrong.any(), (f"{int(wrong.sum())} lane changes away from lane {ex_lane} on the approach, first "
                             f"vehicle {name(ts[ro[ci][wrong][0]])} at x = {xo[ci][wrong][0]:.1f} m: lane "
                             f"{lo[ci - 1][wrong][0]} -> {lo[ci][wrong][0]}")
    lanes_txt = ""
    if p["lanes"] > 1:
        n_wide = mandatory(p, ts, tp["group_id"][()].astype(np.int64), b, ro, ko, xo, lo, same)
        assert n_wide >= int(min_wide), f"{n_wide} wide gaps on the approach (want {min_wide}): not exercised"
        lanes_txt = (f"; {int(on_appr.sum())} lane changes on the approach, all toward lane {ex_lane}, "
                     f"{int(chg.sum())} in all; {n_wide} wide gaps toward it on the approach, each taken at once")
    on_road_b = b & ~crossed & (c == 0)
    print(f"{p['steps'] + 1} frames, {len(x)} points, {n} vehicles: {int(b.sum())} bound (seed draws), "
          f"{int(take.sum())} left from lane {ex_lane} at the end of the step reaching {at:g} m (overshoot up to "
          f"{over.max() if take.any() else 0:.2f} m), {int(miss.sum())} missed it and drove on "
          f"({int(np.sum(one & miss))} reached L), {int(on_road_b.sum())} still before it; {int(one.sum())} reached L "
          f"in all{lanes_txt}")


WIDE_BEHIND_M, WIDE_AHEAD_M = 200.0, 120.0


def mandatory(p, ts, gid, b, ro, ko, xo, lo, same, ending=False):
    """On the approach the change toward the exit lane is mandatory: any safe gap. A gap with nobody within 200 m
    behind and 120 m ahead is safe under b_mandatory (and MOBIL's incentive then does not matter), so a bound vehicle
    ready to change (its group changes lanes, its last change min_interval_s old) beside such a gap in the lane toward
    the exit lane (a lane that does not end) is in it after the step, unless another vehicle changed into that gap in
    the same step (a gap takes one per step). Decisions see the lanes of the previous frame at the positions of this
    one (a change keeps the position; the vehicles that enter in a step enter after the changes). Vehicles in a lane
    that ends (the merge lane) are judged only with ENDING, the others only without. Returns how many such gaps there
    were."""
    at, ex_lane, dt = p["at"], p["exit_lane"], p["dt"]
    sc_groups = p["sc"]["fleet"]["drivers"]
    lc_on, wait = [], []
    for g in sc_groups:
        lc = g.get("lane_change", {"model": "mobil"})
        lc_on.append(lc.get("model", "mobil") != "none")
        wait.append(int(np.ceil(float(lc.get("min_interval_s", 1.0)) / dt - 1e-9)))
    lc_on, wait = np.array(lc_on), np.array(wait)
    # the points that have a previous frame: decision state (lane before, position now) and the state after
    j = np.flatnonzero(same) + 1
    k, x, l_before, l_after, r = ko[j], xo[j], lo[j - 1], lo[j], ro[j]
    # each vehicle's last change before each step (entry counts as ready: lc_ready starts at 0)
    changed = l_after != l_before
    last = np.full(len(j), -10 ** 9)
    idx = np.where(changed, np.arange(len(j)), -1)
    idx = np.maximum.accumulate(idx)       # the latest change at or before this point, in vehicle-then-step order
    seg = np.concatenate([[0], np.cumsum(r[1:] != r[:-1])])
    prev = np.concatenate([[-1], idx[:-1]])
    ok = (prev >= 0) & (seg[np.maximum(prev, 0)] == seg)
    last[ok] = k[prev[ok]]
    ends = np.zeros(p["lanes"], dtype=bool)
    if p["ramp"]:
        ends[0] = True
    for d in p["drops"]:
        ends[int(d["lane"])] = True
    tgt = np.where(l_before > ex_lane, l_before - 1, l_before + 1)
    cand = (b[r] & (x >= at - p["approach"]) & (x < at) & (l_before != ex_lane) & lc_on[gid[r]] &
            (k - last >= wait[gid[r]]) & (k < p["steps"]) & ~ends[np.clip(tgt, 0, p["lanes"] - 1)] &
            (ends[l_before] == ending))
    span = float(p["L"]) * 10.0
    base = (k * 16 + tgt) * span
    sb = np.sort((k * 16 + l_before) * span + x)
    pos = np.searchsorted(sb, base + x)
    behind = np.where(pos > 0, sb[np.maximum(pos - 1, 0)], -np.inf)
    behind = np.where(behind >= base, behind, -np.inf)      # the target lane's vehicle right behind, or none
    ahead = np.where(pos < len(sb), sb[np.minimum(pos, len(sb) - 1)], np.inf)
    ahead = np.where(ahead < base + span, ahead, np.inf)    # and right ahead
    wide = cand & (base + x - behind >= WIDE_BEHIND_M) & (ahead - (base + x) >= WIDE_AHEAD_M)
    # a gap takes one vehicle per step: another one that changed into the same gap in this step took it
    sc = np.sort(((k * 16 + l_after) * span + x)[changed])
    into = np.searchsorted(sc, ahead) - np.searchsorted(sc, behind, side="right")
    contested = wide & (into - (changed & (l_after == tgt)) > 0)
    want = wide & ~contested
    bad = want & (l_after != tgt)
    assert not bad.any(), (f"{int(bad.sum())} of {int(want.sum())} wide gaps on the approach not taken, first vehicle "
                           f"{name(ts[r[bad][0]])} at t = {k[bad][0] * dt:g} s, x = {x[bad][0]:.1f} m, lane "
                           f"{l_before[bad][0]} beside an empty stretch of lane {tgt[bad][0]}")
    return int(want.sum())


def share(path):
    f = h5py.File(path, "r")
    p = setup(f)
    tp, sm = f["trips"], f["summary"]
    c = tp["completed"][()]
    x0 = entry_x(p, tp["serial"][()])
    # reached at_m: completed (at < L), or still on the road past it in the final frame
    reached = (c > 0) & (x0 < p["at"])
    tr = f["trajectories"]
    tk = step_of(tr["t"][()], p["dt"])
    fin = tk == p["steps"]
    assert fin.any(), "no final frame"
    past = tr["serial"][()][fin][tr["x"][()][fin] >= p["at"]]
    reached |= np.isin(tp["serial"][()], past) & (x0 < p["at"])
    n = int(reached.sum())
    nb = int(sm["off_ramp_exits"][()]) + int(sm["missed_exits"][()])
    q = p["share"]
    est = nb / n
    sd = np.sqrt(q * (1 - q) / n)
    z = (est - q) / sd
    assert n >= 500 and abs(z) <= 4.0, f"{nb} of {n} bound: {est:.4f}, share {q}, z = {z:.2f}"
    print(f"{nb} of {n} vehicles that reached {p['at']:g} m were bound for the off-ramp "
          f"({int(sm['off_ramp_exits'][()])} exits + {int(sm['missed_exits'][()])} missed): {est:.4f} against {q} "
          f"+- {sd:.4f} (z = {z:+.2f})")


def all_leave(path):
    f = h5py.File(path, "r")
    p = setup(f)
    assert p["lanes"] == 1 and p["share"] == 1.0, "for share 1 on one lane"
    tp, sm = f["trips"], f["summary"]
    c = tp["completed"][()]
    assert int(np.sum(c == 1)) == 0 and int(sm["exited"][()]) == 0, f"{int(np.sum(c == 1))} trips reached L"
    assert int(sm["missed_exits"][()]) == 0, "missed exits on one lane"
    d = tp["distance"][()][c == 2] - p["at"]     # all enter at 0; below 40 m/s a step covers less than 40 dt
    assert np.all(d >= 0.0) and np.all(d <= 40.0 * p["dt"]), f"exits at at_m + [{d.min():g}, {d.max():g}] m"
    tr = f["trajectories"]
    assert np.all(tr["x"][()] < p["at"]), "a vehicle seen at or past at_m"
    n2 = int(np.sum(c == 2))
    assert n2 > 50, f"only {n2} exits"
    print(f"{n2} of {len(c)} vehicles left at {p['at']:g} m (distances {tp['distance'][()][c == 2].min():.2f} to "
          f"{tp['distance'][()][c == 2].max():.2f} m), none reached L, none seen beyond {p['at']:g} m; "
          f"{int(np.sum(c == 0))} on the road")


def _objects(f):
    d = {"": f}
    f.visititems(lambda name, o: d.__setitem__(name, o))
    return d


def zero_equals(pa, pb):
    a, b = h5py.File(pa, "r"), h5py.File(pb, "r")
    assert setup(a)["off"] and setup(a)["share"] == 0.0 and not setup(b)["off"], "A: share 0, B: no off-ramp"
    oa, ob = _objects(a), _objects(b)
    only = {"summary/off_ramp_exits", "summary/missed_exits"}
    assert set(oa) - set(ob) == only and not set(ob) - set(oa), f"objects: {sorted(set(oa) ^ set(ob))}"
    for k in only:
        assert int(a[k][()]) == 0, f"{k} = {a[k][()]} with share 0"
    skip = {"meta/wall_time_s", "meta/start_time", "meta/phase_time", "meta/scenario_text", "meta/scenario_path"}
    bad, nd, nv = [], 0, 0
    for k, o in ob.items():
        q = oa[k]
        if sorted(o.attrs) != sorted(q.attrs) or any(raw(o.attrs[m]) != raw(q.attrs[m]) for m in o.attrs):
            bad.append(k + " (attributes)")
        if isinstance(o, h5py.Dataset) and k not in skip:
            nd += 1
            nv += o.size
            if o.dtype != q.dtype or raw(o[()]) != raw(q[()]):
                bad.append(k)
    assert not bad, f"differ: {bad}"
    ch = int(b["summary/lane_changes"][()]) if "summary/lane_changes" in b else 0
    print(f"{nd} datasets ({nv} values) and every attribute equal; {int(b['summary/entered'][()])} vehicles, "
          f"{ch} lane changes; the two off-ramp counters 0")


def ahead(pa, pz):
    a, z = h5py.File(pa, "r"), h5py.File(pz, "r")
    p = setup(a)
    assert p["lanes"] == 1, "one lane"
    dt = p["dt"]
    ta, tz = a["trips"], z["trips"]
    sa, sz = ta["serial"][()], tz["serial"][()]
    c = ta["completed"][()]
    exits = np.flatnonzero(c == 2)
    assert len(exits) > 5, "too few exits"
    # exits in serial order (one lane: nobody overtakes); the first exit time among the vehicles ahead of each one
    o = np.argsort(sa)
    ex_t = np.where(c[o] == 2, step_of(np.nan_to_num(ta["exit_time"][()][o]), dt), np.iinfo(np.int64).max)
    assert np.all(np.diff(ex_t[c[o] == 2]) > 0), "off-ramp exits out of serial order on one lane"
    ahead_first = np.minimum.accumulate(np.concatenate([[np.iinfo(np.int64).max], ex_t[:-1]]))  # steps
    limit = dict(zip(sa[o].tolist(), ahead_first.tolist()))
    first_serial = sa[o][c[o] == 2][0]
    b = bound_for(p, sa)
    assert sa[b].min() == first_serial, "the first vehicle bound for the off-ramp (seed draws) is not the first exit"
    # trips of the vehicles ahead of the first exit: bit for bit
    ia, iz = np.flatnonzero(sa < first_serial), np.flatnonzero(sz < first_serial)
    assert len(ia) == len(iz) and np.array_equal(np.sort(sa[ia]), np.sort(sz[iz])), "different vehicles ahead"
    ia, iz = ia[np.argsort(sa[ia])], iz[np.argsort(sz[iz])]
    nvals = 0
    for k in ta:
        assert raw(ta[k][()][ia]) == raw(tz[k][()][iz]), f"trips/{k} of the vehicles ahead of the first exit"
        nvals += len(ia)
    # every trajectory point of each vehicle before the first exit ahead of it; in the frame of that instant (the
    # exit's step end) its position and speed still come from a step with that leader, its acceleration not
    ra, rz = a["trajectories"], z["trajectories"]
    ka, kz = step_of(ra["t"][()], dt), step_of(rz["t"][()], dt)
    BIG = np.iinfo(np.int64).max
    own = dict(zip(sa.tolist(), np.where(c == 2, step_of(np.nan_to_num(ta["exit_time"][()]), dt), BIG).tolist()))
    lim_a = np.array([limit[s] for s in ra["serial"][()].tolist()])
    lim_z = np.array([limit.get(s, -1) for s in rz["serial"][()].tolist()])
    own_z = np.array([own.get(s, BIG) for s in rz["serial"][()].tolist()])
    n_pts = 0
    for cols, at_lim in ((("t", "serial", "x", "v"), True), (("a", "fuel_rate"), False)):
        keep_a = (ka <= lim_a) if at_lim else (ka < lim_a)
        # in the share-0 run the same vehicles, and a bound one only before its own exit
        keep_z = ((kz <= lim_z) if at_lim else (kz < lim_z)) & (kz < own_z)
        assert keep_a.sum() == keep_z.sum(), f"{keep_a.sum()} points to compare, {keep_z.sum()} in the share-0 run"
        for col in cols:
            xa, xz = ra[col][()][keep_a], rz[col][()][keep_z]
            assert raw(xa) == raw(xz), f"trajectories/{col}: {int(np.sum(xa != xz))} points differ"
        n_pts = max(n_pts, int(keep_a.sum()))
    # and not vacuous: the vehicle right behind the first exit is affected
    nxt = sa[o][np.searchsorted(sa[o], first_serial) + 1]
    assert (ta["fuel"][()][sa == nxt] != tz["fuel"][()][sz == nxt]).all(), \
        "the vehicle behind the first exit drove the same trip as without the exit"
    print(f"{len(ia)} trips ahead of the first exit (serial {first_serial:.0f}) equal ({nvals} values), and "
          f"{n_pts} of {len(ka)} trajectory points (each vehicle's until a vehicle ahead of it left); "
          f"{len(exits)} exits; the vehicle behind the first differs")


def merge(pa, pz):
    out = []
    for path in (pa, pz):
        f = h5py.File(path, "r")
        p = setup(f)
        assert p["ramp"], "with an on-ramp"
        dt, end = p["dt"], float(p["ramp"]["end_m"])
        tr = f["trajectories"]
        k, lane, s, x, v = (step_of(tr["t"][()], dt), tr["lane"][()], tr["serial"][()], tr["x"][()], tr["v"][()])
        m = lane == 0
        # each vehicle's time in the merge lane: its frames there
        us, cnt = np.unique(s[m], return_counts=True)
        j = int(np.argmax(cnt)) if len(cnt) else -1
        worst = dict(t=cnt[j] * dt if j >= 0 else 0.0, n=len(us))
        if j >= 0:
            w = m & (s == us[j])
            worst.update(who=name(us[j]), bound=bool(p["off"] and bound_for(p, [us[j]])[0]), x=float(x[w][-1]),
                         still=bool(k[w][-1] == p["steps"]))
        if p["off"]:
            # bound vehicles in the merge lane beside wide gaps of lane 1 on the approach: each takes its gap
            tp = f["trips"]
            ts = tp["serial"][()]
            so = np.argsort(ts)
            row = so[np.searchsorted(ts[so], s)]
            o = np.lexsort((k, row))
            try:
                worst["wide"] = mandatory(p, ts, tp["group_id"][()].astype(np.int64), bound_for(p, ts), row[o], k[o],
                                          x[o], lane[o].astype(np.int64), row[o][1:] == row[o][:-1], ending=True)
            except AssertionError as e:
                worst["wide"] = str(e)
        stuck = np.unique(s[m & (v < 0.1) & (x > end - 20.0) & (k == p["steps"])])
        worst["stuck"] = len(stuck)
        worst["stuck_bound"] = int(bound_for(p, stuck).sum()) if p["off"] and len(stuck) else 0
        out.append(worst)
    wa, wz = out
    end = float(setup(h5py.File(pa, "r"))["ramp"]["end_m"])
    problems = []
    if isinstance(wa["wide"], str):
        problems.append(f"in the merge lane {wa['wide']}")
    if not wa["t"] <= 2.0 * wz["t"] + 30.0 or wa["stuck"]:
        till = " to the end of the run" if wa["still"] else ""
        problems.append(f"vehicle {wa['who']} ({'bound for the off-ramp' if wa['bound'] else 'not bound'}) stays "
                        f"{wa['t']:g} s in the merge lane{till}, last at x = {wa['x']:.1f} m (its end: {end:g} m; "
                        f"with share 0 nobody stays more than {wz['t']:g} s); {wa['stuck']} vehicles stand at its end "
                        f"at the end of the run, {wa['stuck_bound']} of them bound")
    assert not problems, "; ".join(problems) + (": a vehicle bound for the off-ramp in the merge lane on the approach "
                                                "does not leave it")
    print(f"longest stay in the merge lane {wa['t']:g} s (share 0: {wz['t']:g} s) over {wa['n']} vehicles; none stuck "
          f"at its end; {wa['wide']} wide gaps beside bound vehicles in it on the approach, each taken at once")


def coop(pa, pn):
    a, z = h5py.File(pa, "r"), h5py.File(pn, "r")
    p = setup(a)
    dt, at, ex_lane = p["dt"], p["at"], p["exit_lane"]
    cols = ("t", "serial", "lane", "x", "v", "a")
    ra = {k: a["trajectories"][k][()] for k in cols}
    rz = {k: z["trajectories"][k][()] for k in cols}
    n = min(len(ra["t"]), len(rz["t"]))
    diff = np.zeros(n, dtype=bool)
    for k in cols:
        diff |= ra[k][:n] != rz[k][:n]
    assert diff.any(), "the runs with and without yielding are the same: nobody asked on the approach, or none yielded"
    ka, kz = step_of(ra["t"], dt), step_of(rz["t"], dt)
    k0 = ka[np.argmax(diff)]
    fa, fz = np.flatnonzero(ka == k0), np.flatnonzero(kz == k0)
    # the first frame that differs: the same vehicles, places and speeds (yielding acts on the step's acceleration)
    assert len(fa) == len(fz), f"t = {k0 * dt:g} s: {len(fa)} vehicles, {len(fz)} without yielding"
    for k in ("serial", "lane", "x", "v"):
        assert raw(ra[k][fa]) == raw(rz[k][fz]), f"t = {k0 * dt:g} s: {k} differs before any acceleration did"
    s, lane, x = ra["serial"][fa], ra["lane"][fa].astype(np.int64), ra["x"][fa]
    d = np.flatnonzero(ra["a"][fa] != rz["a"][fz])
    # the askers: bound, on the approach, in a lane beyond the exit lane; each asks the last vehicle behind it in the
    # lane to its right
    b = bound_for(p, s)
    askers = np.flatnonzero(b & (x >= at - p["approach"]) & (x < at) & (lane > ex_lane))
    follower = {}
    for i in askers:
        behind = np.flatnonzero((lane == lane[i] - 1) & (x < x[i]))
        if len(behind):
            follower[int(behind[np.argmax(x[behind])])] = int(i)
    accounts = []
    for j in d:
        assert j in follower, (f"t = {k0 * dt:g} s: vehicle {s[j]:.0f} (lane {lane[j]}, x = {x[j]:.1f} m) changes its "
                               f"acceleration but follows no vehicle asking to reach lane {ex_lane}")
        assert ra["a"][fa][j] < rz["a"][fz][j], f"vehicle {s[j]:.0f} accelerates harder when it yields"
        i = follower[j]
        accounts.append(f"vehicle {name(s[j])} in lane {lane[j]} at {x[j]:.1f} m yields to {name(s[i])} in lane "
                        f"{lane[i]} at {x[i]:.1f} m ({rz['a'][fz][j]:.3f} -> {ra['a'][fa][j]:.3f} m/s2)")
    print(f"first difference at t = {k0 * dt:g} s, {len(askers)} asking: " + "; ".join(accounts) +
          f"; missed exits {int(a['summary/missed_exits'][()])} (none yielding: {int(z['summary/missed_exits'][()])})")


def identical(pa, pb, min_n):
    a, b = h5py.File(pa, "r"), h5py.File(pb, "r")
    timing = {"meta/wall_time_s", "meta/start_time", "meta/threads", "meta/phase_time"}
    oa, ob = _objects(a), _objects(b)
    assert set(oa) == set(ob), f"objects in one file only: {sorted(set(oa) ^ set(ob))}"
    bad, nd = [], 0
    for k, o in oa.items():
        q = ob[k]
        if sorted(o.attrs) != sorted(q.attrs) or any(raw(o.attrs[m]) != raw(q.attrs[m]) for m in o.attrs):
            bad.append(k + " (attributes)")
        if isinstance(o, h5py.Dataset):
            nd += 1
            if k not in timing and (o.dtype != q.dtype or raw(o[()]) != raw(q[()])):
                bad.append(k)
    assert not bad, f"differ: {bad}"
    assert int(a["meta/completed"][()]) == 1 and int(b["meta/completed"][()]) == 1, "incomplete"
    n2, nm = int(a["summary/off_ramp_exits"][()]), int(a["summary/missed_exits"][()])
    assert n2 > 0 and nm > 0, f"{n2} off-ramp exits, {nm} missed: not exercised"
    most = int(a["lanes/vehicles"][()].max()) if "lanes" in a else int(a["timeseries/vehicles"][()].max())
    assert most > int(min_n), f"at most {most} vehicles in a lane (want > {min_n})"
    ch = int(a["summary/lane_changes"][()]) if "summary/lane_changes" in a else 0
    busy = ""
    if int(min_n) > 0:
        # off-ramp exits while some lane held more than MIN_N vehicles (the kernel on threads)
        per = a["lanes/vehicles"][()].max(axis=1) if "lanes" in a else a["timeseries/vehicles"][()]
        t_busy = a["timeseries/t"][()][np.argmax(per > int(min_n))]
        c = a["trips/completed"][()]
        n_busy = int(np.sum(a["trips/exit_time"][()][c == 2] > t_busy))
        assert n_busy > 0, f"no off-ramp exit after t = {t_busy:g} s, when a lane first held more than {min_n}"
        busy = f" ({n_busy} exits after t = {t_busy:g} s, when a lane first held more than {min_n})"
    print(f"{nd} datasets and their attributes equal: {n2} off-ramp exits{busy}, {nm} missed, {ch} lane changes, up to "
          f"{most} vehicles in a lane, {a['trips/serial'].shape[0]} trips")


def interrupted(path):
    f = h5py.File(path, "r")
    c = f["trips/completed"][()]
    print(int(f["meta/steps_done"][()]), int(np.sum(c == 2)))


if __name__ == "__main__":
    cmd, args = sys.argv[1], sys.argv[2:]
    try:
        {"conserve": conserve, "frames": frames, "share": share, "all_leave": all_leave, "zero_equals": zero_equals,
         "ahead": ahead, "merge": merge, "coop": coop, "identical": identical, "interrupted": interrupted}[cmd](*args)
    except AssertionError as e:
        print(f"{cmd}: {e}")
        sys.exit(1)
