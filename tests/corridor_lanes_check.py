"""Checks of multi-lane corridor results for tests/t_corridor_lanes.sh, one subcommand per check; each exits non-zero
with the reason on failure and prints a one-line account of what it measured on success.

  same_lane MULTI.h5 SINGLE.h5 LANE     lane LANE of MULTI equals the single-lane corridor SINGLE, bit for bit: every
                                        trip (serial = LANE 2^40 + SINGLE's serial), its trajectory points, and the
                                        lane's /lanes columns against SINGLE's /timeseries
  noise_apart MULTI.h5                  lanes 0 and 1 (same demand, lane changes off) do not drive the same trips
  identical A.h5 B.h5 MIN_LANE_N        every dataset and attribute equal bit for bit (meta wall times, threads left
                                        out), with lane changes and more than MIN_LANE_N vehicles in some lane
  physical FILE.h5 STEPS,...            frames written every step: order and positive gaps in each lane, vehicles
                                        conserved against /trips, every lane change and cut-in seen between frames
                                        counted in /trips and in /lanes (per record, pair, lane, group), the records'
                                        lanes from the frames, detector counts and Edie's distance from /trips and
                                        the last frame, min_interval_s of each group (STEPS: in steps, per group),
                                        the ballistic update across changes
  redistribute FILE.h5 X0 T0 OP SHARE   lane 0's share of the lanes' mean density over x >= X0, t >= T0 (from the
                                        frames), compared (lt/gt) with SHARE: its distance from an even split
  lanes_sums FILE.h5 [RUN_LOG]          /lanes against /timeseries, /summary, /trips and the printed summary line
"""
import re
import sys

import h5py
import numpy as np

from lanes_check import lane_rates, v_stop_of  # the same /lanes checks as the ring's

LANE_KEY = 2 ** 40  # lane l's vehicles are numbered from l 2^40 (src/core/corridor.c, lane_key)


def raw(x):
    x = np.asarray(x)
    return (x.dtype.str, x.shape, x.tobytes()) if x.dtype.kind in "fiub" else (x.shape, x.tolist())


def datasets(f):
    d = {}
    f.visititems(lambda n, o: d.__setitem__(n, o) if isinstance(o, h5py.Dataset) else None)
    return d


def step_of(t, dt):
    """Step index of times written as k dt."""
    k = np.rint(np.asarray(t) / dt)
    assert np.all(np.abs(k * dt - t) <= 1e-9 * np.maximum(1.0, np.abs(t))), "times off the step grid"
    return k.astype(np.int64)


def same_lane(multi, single, lane):
    a, b = h5py.File(multi, "r"), h5py.File(single, "r")
    lane = int(lane)
    ta, tb = a["trips"], b["trips"]
    m = ta["lane"][()] == lane
    sa = ta["serial"][()][m]
    oa, ob = np.argsort(sa, kind="stable"), np.argsort(tb["serial"][()], kind="stable")
    assert len(oa) == len(ob) and len(ob) > 50, f"lane {lane}: {len(oa)} trips, single lane: {len(ob)}"
    assert np.all(ta["lane_changes"][()][m] == 0), "a vehicle changed lanes with lane_change: none"
    # serials: lane l's n-th vehicle is l 2^40 + n, the single lane's n (float64 holds both exactly)
    want = tb["serial"][()][ob] + float(lane * LANE_KEY)
    assert raw(sa[oa]) == raw(want), f"serials differ: {sa[oa][:3]} vs {want[:3]}"
    skip = {"serial", "lane", "lane_changes"}
    names = [k for k in tb if k not in skip]
    for k in ("arrival_time", "entry_time", "exit_time", "fuel", "distance", "class_id", "group_id"):
        assert k in names, k
    checked = 0
    for k in names:
        assert k in ta, f"trips/{k} missing from the multi-lane result"
        xa, xb = ta[k][()][m][oa], tb[k][()][ob]
        if raw(xa) != raw(xb):
            d = np.nonzero(~((xa == xb) | (np.isnan(xa) & np.isnan(xb))))[0]
            raise AssertionError(f"trips/{k}: {len(d)} of {len(xa)} differ, first serial {int(tb['serial'][ob][d[0]])}"
                                 f": {xa[d[0]]!r} != {xb[d[0]]!r}")
        checked += xa.size
    # trajectory points: lane after lane, each front first, so lane l's points in file order are the single lane's
    pa, pb = a["trajectories"], b["trajectories"]
    mp = pa["lane"][()] == lane
    npts = int(mp.sum())
    assert npts == pb["t"].shape[0] and npts > 1000, f"{npts} points in lane {lane}, {pb['t'].shape[0]} single"
    for k in ("t", "x", "v", "a", "fuel_rate"):
        xa, xb = pa[k][()][mp], pb[k][()]
        assert raw(xa) == raw(xb), f"trajectories/{k}: max |diff| {np.max(np.abs(xa - xb))}"
        checked += npts
    assert raw(pa["serial"][()][mp]) == raw(pb["serial"][()] + float(lane * LANE_KEY)), "trajectories/serial"
    # the lane's record (/lanes) against the single lane's /timeseries (the same sums, taken apart)
    la, ts = a["lanes"], b["timeseries"]
    assert raw(la["t"][()]) == raw(ts["t"][()]), "record times"
    n = la["vehicles"][()][:, lane]
    assert raw(n) == raw(ts["vehicles"][()]), "lanes/vehicles"
    busy = n > 0
    for k in ("mean_speed", "sd_speed", "waves"):
        xa, xb = la[k][()][:, lane][busy], ts[k][()][busy]
        assert raw(xa) == raw(xb), f"lanes/{k} vs timeseries/{k}: max |diff| {np.max(np.abs(xa - xb))}"
        checked += xa.size
    # the road's fuel rate is summed class by class, the lane's vehicle by vehicle: equal up to rounding
    fa, fb = la["fuel_rate"][()][:, lane], ts["fuel_rate"][()]
    assert np.allclose(fa, fb, rtol=1e-12, atol=0), f"lanes/fuel_rate: max |diff| {np.max(np.abs(fa - fb))}"
    g = n > 1
    assert raw(la["mean_gap"][()][:, lane][g]) == raw(ts["mean_gap"][()][g]), "lanes/mean_gap vs timeseries/mean_gap"
    print(f"lane {lane}: {len(ob)} trips, {npts} trajectory points, {int(busy.sum())} records; {checked} values equal")


def noise_apart(path):
    f = h5py.File(path, "r")
    t = f["trips"]
    lane, serial = t["lane"][()], t["serial"][()]
    by = []
    for l in (0, 1):
        m = lane == l
        o = np.argsort(serial[m])
        by.append((t["entry_time"][()][m][o], t["fuel"][()][m][o]))
    n = min(len(by[0][0]), len(by[1][0]))
    # twins: the n-th vehicles of both lanes, entered at the same instant
    twins = by[0][0][:n] == by[1][0][:n]
    assert twins.sum() > 20, f"only {twins.sum()} of {n} pairs entered together: no like-for-like"
    same = int(np.sum((by[0][1][:n] == by[1][1][:n])[twins]))
    assert same < twins.sum() // 10, (f"{same} of {twins.sum()} twins burn the same fuel to the bit: the lanes draw "
                                      f"the same acceleration noise")
    print(f"{twins.sum()} twins (the n-th vehicles of both lanes, entered at the same instant), {same} with equal fuel")


def identical(pa, pb, min_lane_n):
    a, b = h5py.File(pa, "r"), h5py.File(pb, "r")
    timing = {"meta/wall_time_s", "meta/start_time", "meta/threads", "meta/phase_time"}
    objs = []
    for f in (a, b):
        d = {"": f}
        f.visititems(lambda n, o: d.__setitem__(n, o))
        objs.append(d)
    oa, ob = objs
    assert set(oa) == set(ob), f"objects in one file only: {sorted(set(oa) ^ set(ob))}"
    bad, n_data = [], 0
    for k, o in oa.items():
        p = ob[k]
        if sorted(o.attrs) != sorted(p.attrs) or any(raw(o.attrs[q]) != raw(p.attrs[q]) for q in o.attrs):
            bad.append(k + " (attributes)")
        if isinstance(o, h5py.Dataset):
            n_data += 1
            if k not in timing and (o.dtype != p.dtype or raw(o[()]) != raw(p[()])):
                bad.append(k)
    assert not bad, f"differ: {bad}"
    changes = int(a["summary/lane_changes"][()])
    most = int(a["lanes/vehicles"][()].max())
    assert changes > 0, "no lane changes: the comparison would not exercise them"
    assert most > int(min_lane_n), f"at most {most} vehicles in a lane (want > {min_lane_n})"
    assert int(a["meta/completed"][()]) == 1 and int(b["meta/completed"][()]) == 1, "incomplete"
    print(f"{n_data} datasets and their attributes equal, {changes} lane changes, up to {most} vehicles in a lane, "
          f"{a['trips/serial'].shape[0]} trips")


def frames(f):
    """The trajectory points with each point's step, lane, the vehicle's row in /trips, and the frames' bounds."""
    dt = float(f["meta/dt"][()])
    tr, tp = f["trajectories"], f["trips"]
    k = step_of(tr["t"][()], dt)
    serial = tr["serial"][()]
    ts = tp["serial"][()]
    order = np.argsort(ts)
    row = order[np.searchsorted(ts[order], serial)]
    assert np.array_equal(ts[row], serial), "a trajectory point's vehicle has no trip"
    assert np.all(np.diff(k) >= 0), "frames out of order"
    bounds = np.flatnonzero(np.diff(np.concatenate([[-1], k, [k[-1] + 1]])))
    return dt, k, serial, row, bounds


def physical(path, min_steps):
    f = h5py.File(path, "r")
    dt, k, serial, row, bounds = frames(f)
    tr, tp = f["trajectories"], f["trips"]
    x, v, a, lane = tr["x"][()], tr["v"][()], tr["a"][()], tr["lane"][()].astype(np.int64)
    length = f["classes/length"][()][tp["class_id"][()].astype(np.int64)]
    L = float(f["meta/road_length"][()])
    n_steps = int(f["meta/steps_done"][()])
    steps = k[bounds[:-1]]
    # a frame every step (an empty road writes no points: those steps are checked below to be empty)
    assert np.all(np.diff(steps) >= 1) and steps[-1] == n_steps and len(steps) > n_steps // 2, "frames every step"
    # every frame: each lane's points front first with positive gaps (the leader's rear ahead of the follower's front)
    key = k * 16 + lane
    assert np.all(np.diff(key) >= 0), "points not lane after lane within a frame"
    same = key[1:] == key[:-1]
    gap = x[:-1] - length[row[:-1]] - x[1:]
    assert np.all(gap[same] > 0), f"gap {gap[same].min():g} m at t = {k[1:][same][np.argmin(gap[same])] * dt:g} s"
    assert np.all((x >= 0) & (x < L)), "a point off the road"
    # conservation: frame k holds exactly the vehicles entered at or before k dt and not exited by then
    ent = step_of(tp["entry_time"][()], dt)
    done = tp["completed"][()] == 1
    ex = np.full(len(ent), np.iinfo(np.int64).max)
    ex[done] = step_of(tp["exit_time"][()][done], dt)
    on = np.zeros(n_steps + 1, dtype=np.int64)
    at = dict(zip(steps.tolist(), range(len(steps))))
    for s in range(n_steps + 1):
        j = at.get(s)
        got = np.sort(serial[bounds[j]:bounds[j + 1]]) if j is not None else np.zeros(0)
        want = np.sort(tp["serial"][()][(ent <= s) & (ex > s)])
        assert np.array_equal(got, want), f"t = {s * dt:g} s: {len(got)} on the road, /trips says {len(want)}"
        on[s] = len(got)
    ts = f["timeseries"]
    rk = step_of(ts["t"][()], dt)
    assert np.array_equal(ts["vehicles"][()], on[rk]), "timeseries/vehicles"
    assert np.array_equal(ts["entered"][()] - ts["exited"][()], on[rk]), "entered - exited != on the road"
    # lane changes: a vehicle in consecutive frames with another lane changed at the later step
    o = np.lexsort((k, serial))
    cont = (serial[o][1:] == serial[o][:-1])
    assert np.all(k[o][1:][cont] - k[o][:-1][cont] == 1), "a vehicle missing from a frame"
    dl = lane[o][1:] - lane[o][:-1]
    chg = cont & (dl != 0)
    assert np.all(np.abs(dl[cont]) <= 1), "a vehicle moved more than one lane in a step"
    who, when = row[o][1:][chg], k[o][1:][chg]
    seen = np.bincount(who, minlength=len(ent))
    assert np.array_equal(seen, tp["lane_changes"][()].astype(np.int64)), \
        f"/trips lane_changes differ from the frames for {int(np.sum(seen != tp['lane_changes'][()]))} vehicles"
    assert len(who) > 0, "no lane changes"
    assert when.min() >= 1 and when.max() < n_steps, "a change at step 0 or at the final instant"
    # trips end in the lane of their last frame
    last = np.ones(len(o), dtype=bool)
    last[:-1] = ~cont
    assert np.array_equal(tp["lane"][()][row[o][last]], lane[o][last]), "/trips lane differs from the last frame"
    # each record's lane changes are those of the steps since the previous record
    lk = step_of(f["lanes/t"][()], dt)
    per = np.array([np.sum((when > lo) & (when <= hi)) for lo, hi in zip(np.concatenate([[-1], lk[:-1]]), lk)])
    assert np.array_equal(per, f["lanes/lane_changes"][()]), "/lanes/lane_changes differ from the frames"
    # cut-ins: a changer with a vehicle right behind it in its new lane's frame (not one that entered in that step:
    # entries come after the changes) cut in front of that vehicle
    at_pt = o[1:][chg]                                    # the changer's point in the frame of its change
    nxt = np.minimum(at_pt + 1, len(x) - 1)
    behind = (at_pt + 1 < len(x)) & (key[nxt] == key[at_pt])
    behind &= ent[row[nxt]] != k[at_pt]
    fol = row[nxt][behind]
    cut_when, cut_lane = k[at_pt][behind], lane[at_pt][behind]
    per_cut = np.array([np.sum((cut_when > lo) & (cut_when <= hi))
                        for lo, hi in zip(np.concatenate([[-1], lk[:-1]]), lk)])
    la = f["lanes"]
    assert np.array_equal(per_cut, la["cut_ins"][()]), "/lanes/cut_ins differ from the frames"
    n_lanes = la["vehicles"].shape[1]
    assert np.array_equal(np.bincount(cut_lane, minlength=n_lanes), la["lane_cut_ins"][()]), "lane_cut_ins"
    per_step = {int(k[bounds[j]]): (lane[bounds[j]:bounds[j + 1]], v[bounds[j]:bounds[j + 1]])
                for j in range(len(bounds) - 1)}
    empty = (np.zeros(0, dtype=np.int64), np.zeros(0))
    rec = [per_step.get(int(s), empty) for s in lk]
    rates = lane_rates(la, [per_step.get(s, empty)[0] for s in range(n_steps)], n_lanes, dt,
                       ([r[0] for r in rec], [r[1] for r in rec]), v_stop_of(f))
    n_groups = len(la["group_cut_ins"][()])
    gid_all = tp["group_id"][()].astype(np.int64)
    assert np.array_equal(np.bincount(gid_all[fol], minlength=n_groups), la["group_cut_ins"][()]), "group_cut_ins"
    assert np.array_equal(np.bincount(gid_all[who], minlength=n_groups), la["group_lane_changes"][()]), \
        "group_lane_changes"
    old_l = lane[o][:-1][chg]
    pair = np.zeros((n_lanes, n_lanes), dtype=np.int64)
    np.add.at(pair, (old_l, lane[at_pt]), 1)
    assert np.array_equal(pair, la["pair_changes"][()]), "pair_changes differ from the frames"
    # each record's lanes from the frame at its instant: vehicles, mean speed, mean gap
    for j, s in enumerate(lk):
        jf = at.get(int(s))
        for l in range(n_lanes):
            sel = np.arange(bounds[jf], bounds[jf + 1]) if jf is not None else np.zeros(0, dtype=np.int64)
            sel = sel[lane[sel] == l]
            assert la["vehicles"][j, l] == len(sel), f"t = {s * dt:g} s lane {l}: vehicles"
            if len(sel):
                assert abs(la["mean_speed"][j, l] - v[sel].mean()) <= 1e-12 * max(1.0, v[sel].mean()), "mean_speed"
            if len(sel) > 1:
                g = gap[sel[:-1]].mean()
                assert abs(la["mean_gap"][j, l] - g) <= 1e-9 * max(1.0, g), f"t = {s * dt:g} s lane {l}: mean_gap"
    # detectors and Edie over all lanes: every completed trip passed each detector and drove L inside the road, an
    # unfinished one passed the detectors behind its last position and drove up to it (all enter at x = 0)
    fin = tp["completed"][()] == 1
    last_x = np.full(len(ent), np.nan)
    final = np.arange(bounds[-2], bounds[-1]) if steps[-1] == n_steps else np.zeros(0, dtype=np.int64)
    last_x[row[final]] = x[final]
    assert np.all(np.isfinite(last_x[~fin])), "an unfinished trip missing from the last frame"
    det = f["detectors"]
    for j, xd in enumerate(det["x"][()]):
        want = int(fin.sum() + np.sum(last_x[~fin] > xd))
        assert int(det["count"][()][:, j].sum()) == want, f"detector at {xd:g} m counts {det['count'][()][:, j].sum()}"
    d_edie = float(f["edie/distance"][()].sum())
    d_want = fin.sum() * L + float(np.sum(last_x[~fin]))
    assert abs(d_edie - d_want) <= 1e-9 * d_want, f"Edie distance {d_edie} m, the trips drove {d_want} m on the road"
    # min_interval_s of each group, in steps
    want = {g: int(w) for g, w in enumerate(min_steps.split(","))}
    worst = {}
    vo = np.lexsort((when, who))
    same_v = who[vo][1:] == who[vo][:-1]
    d = (when[vo][1:] - when[vo][:-1])[same_v]
    gid = tp["group_id"][()][who[vo][1:][same_v]].astype(np.int64)
    for g, w in want.items():
        dg = d[gid == g]
        if len(dg):
            worst[g] = int(dg.min())
            assert dg.min() >= w, f"group {g}: changes {dg.min()} steps apart (least {w})"
    # each vehicle's ballistic update from frame to frame, through its changes (where it keeps moving)
    xs, vs, as_ = x[o], v[o], a[o]
    mv = cont & (vs[1:] > 0)
    ex_x = np.abs(xs[1:] - xs[:-1] - vs[:-1] * dt - 0.5 * as_[:-1] * dt * dt)[mv]
    ex_v = np.abs(vs[1:] - vs[:-1] - as_[:-1] * dt)[mv]
    assert int(f["summary/overlaps"][()]) == 0, "overlaps repaired"
    assert ex_x.max() < 1e-9 * L and ex_v.max() < 1e-9, (ex_x.max(), ex_v.max())
    print(f"{n_steps + 1} steps, {len(x)} points: least gap {gap[same].min():.3f} m, up to {on.max()} on the road, "
          f"{len(who)} lane changes and {len(fol)} cut-ins seen and counted (by {len(np.unique(who))} vehicles), "
          f"least steps between a vehicle's changes per group {worst} (least allowed {want}); {rates}")


def redistribute(path, x0, t0, op, share):
    f = h5py.File(path, "r")
    tr = f["trajectories"]
    x, t, lane = tr["x"][()], tr["t"][()], tr["lane"][()].astype(np.int64)
    m = (x >= float(x0)) & (t >= float(t0))
    n_frames = len(np.unique(t[t >= float(t0)]))
    dens = np.bincount(lane[m], minlength=2)[:2] / n_frames / ((float(f["meta/road_length"][()]) - float(x0)) / 1e3)
    s0 = dens[0] / dens.sum()
    sh = [float(q) for q in re.findall(r"lane_shares:\s*\[([^\]]*)\]", f["meta/scenario_text"][()].decode())[0]
          .split(",")]
    changes = int(f["summary/lane_changes"][()])
    ok = abs(s0 - 0.5) < float(share) if op == "lt" else abs(s0 - 0.5) > float(share)
    msg = (f"entry shares {sh}, lane densities {dens[0]:.2f} and {dens[1]:.2f} veh/km over x >= {x0} m, t >= {t0} s: "
           f"lane 0 holds {s0:.3f}, |{s0:.3f} - 0.5| = {abs(s0 - 0.5):.3f} (want {op} {share}); {changes} lane changes")
    assert ok, msg
    print(msg)


def lanes_sums(path, log=None):
    f = h5py.File(path, "r")
    la, ts, sm, tp = f["lanes"], f["timeseries"], f["summary"], f["trips"]
    assert raw(la["t"][()]) == raw(ts["t"][()]), "/lanes/t differs from /timeseries/t"
    veh = la["vehicles"][()]
    n_lanes = veh.shape[1]
    assert np.array_equal(veh.sum(axis=1), ts["vehicles"][()]), "sum of /lanes/vehicles != /timeseries/vehicles"
    L = float(f["meta/road_length"][()])
    assert np.allclose(la["density"][()], veh / (L / 1e3), rtol=1e-14, atol=0), "density != vehicles / L"
    busy = ts["vehicles"][()] > 0
    mv = np.sum(np.where(veh > 0, la["mean_speed"][()] * veh, 0.0), axis=1)[busy] / ts["vehicles"][()][busy]
    assert np.allclose(mv, ts["mean_speed"][()][busy], rtol=1e-12, atol=0), "lanes' mean speeds, weighted"
    assert np.allclose(la["fuel_rate"][()].sum(axis=1), ts["fuel_rate"][()], rtol=1e-12, atol=1e-12), "fuel rates"
    changes = int(sm["lane_changes"][()])
    cuts = int(sm["cut_ins"][()])
    pair = la["pair_changes"][()]
    sums = {"/lanes/lane_changes": int(la["lane_changes"][()].sum()), "/lanes/pair_changes": int(pair.sum()),
            "/lanes/group_lane_changes": int(la["group_lane_changes"][()].sum()),
            "/trips/lane_changes": int(tp["lane_changes"][()].sum())}
    assert all(s == changes for s in sums.values()), f"/summary/lane_changes {changes}, {sums}"
    far = np.abs(np.subtract.outer(np.arange(n_lanes), np.arange(n_lanes))) != 1
    assert np.all(pair[far] == 0), f"pair_changes between lanes that are not neighbours: {pair.tolist()}"
    csum = {"/lanes/cut_ins": int(la["cut_ins"][()].sum()), "/lanes/lane_cut_ins": int(la["lane_cut_ins"][()].sum()),
            "/lanes/group_cut_ins": int(la["group_cut_ins"][()].sum())}
    assert all(s == cuts for s in csum.values()), f"/summary/cut_ins {cuts}, {csum}"
    assert 0 <= cuts <= changes, (cuts, changes)
    # each group's cut-ins per hour that its vehicles spent on the road (trips: exit, or the end, minus entry)
    end = float(f["meta/steps_done"][()]) * float(f["meta/dt"][()])
    stay = np.where(tp["completed"][()] == 1, tp["exit_time"][()], end) - tp["entry_time"][()]
    gid = tp["group_id"][()].astype(np.int64)
    hours = np.bincount(gid, weights=stay, minlength=len(la["group_cut_ins"])) / 3600.0
    rate = np.where(hours > 0, la["group_cut_ins"][()] / np.where(hours > 0, hours, 1.0), 0.0)
    assert np.allclose(la["group_cut_in_rate"][()], rate, rtol=1e-9, atol=0), \
        f"group_cut_in_rate {la['group_cut_in_rate'][()]} vs {rate} from /trips"
    line = ""
    if log:
        text = open(log).read()
        mm = re.search(r"\| lane changes (\d+) \| cut-ins (\d+)\s*$", text, re.M)
        assert mm, "the summary line does not end with | lane changes N | cut-ins M"
        assert (int(mm.group(1)), int(mm.group(2))) == (changes, cuts), f"printed {mm.group(0)}"
        line = ", printed alike"
    print(f"{len(veh)} records x {n_lanes} lanes: vehicles, speeds, fuel add up; {changes} lane changes and {cuts} "
          f"cut-ins in /summary, /lanes (per record, pairs, groups) and /trips{line}; cut-in rates {rate.round(3)}")


if __name__ == "__main__":
    cmd, args = sys.argv[1], sys.argv[2:]
    try:
        {"same_lane": same_lane, "noise_apart": noise_apart, "identical": identical, "physical": physical,
         "redistribute": redistribute, "lanes_sums": lanes_sums}[cmd](*args)
    except AssertionError as e:
        print(f"{cmd}: {e}")
        sys.exit(1)
