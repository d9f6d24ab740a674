"""Checks of multi-lane ring results for tests/t_lanes.sh, one subcommand per check; each exits non-zero with the
reason on failure and prints a one-line account of what it measured on success.

  same_lane MULTI.h5 SINGLE.h5 FIRST N   vehicles FIRST..FIRST+N-1 of MULTI equal vehicles 0..N-1 of SINGLE, bit for bit
  equalise FILE.h5 TOL                   lane counts of a 2-lane ring within TOL of each other over the last third
  lane_share FILE.h5 OP SHARE            lane 0's mean count over the second half, compared (gt/le) with SHARE * N
  identical A.h5 B.h5                    every dataset equal bit for bit (meta wall times, threads left out)
  physical FILE.h5                       per-frame lane order, positive gaps, conservation, counted lane changes,
                                         each vehicle's ballistic update across its changes
"""
import sys

import h5py
import numpy as np


def raw(x):
    x = np.asarray(x)
    return (x.dtype.str, x.shape, x.tobytes()) if x.dtype.kind in "fiub" else (x.shape, x.tolist())


def datasets(f):
    d = {}
    f.visititems(lambda n, o: d.__setitem__(n, o) if isinstance(o, h5py.Dataset) else None)
    return d


def same_lane(multi, single, first, n):
    a, b = h5py.File(multi, "r"), h5py.File(single, "r")
    first, n = int(first), int(n)
    cols = slice(first, first + n)
    checked = 0
    ta, tb = a["trajectories"], b["trajectories"]
    assert raw(ta["t"][()]) == raw(tb["t"][()]), "trajectory times differ"
    for k in ("x", "v", "a", "fuel_rate"):
        xa, xb = ta[k][()][:, cols], tb[k][()]
        assert xb.shape[1] == n, (k, xb.shape)
        assert xa.dtype == np.float64 and raw(xa) == raw(xb), f"trajectories/{k}: max |diff| {np.max(np.abs(xa - xb))}"
        checked += xa.size
    lane = ta["lane"][()][:, cols]
    assert np.all(lane == lane[0, 0]), "a vehicle changed lanes with lane_change: none"
    skip = {"group_id", "final_lane", "lane_changes", "cut_ins"}
    va, vb = a["vehicles"], b["vehicles"]
    names = [k for k in vb if k not in skip]
    for k in ("final_x", "final_v", "fuel", "distance"):
        assert k in names, k
    for k in names:
        assert k in va, f"vehicles/{k} missing from the multi-lane result"
        xa, xb = va[k][()][cols], vb[k][()]
        if k.startswith("param_") and np.all(np.isnan(xb)):
            continue
        assert raw(xa) == raw(xb), f"vehicles/{k}: {xa} != {xb}"
        checked += xa.size
    assert int(np.sum(va["lane_changes"][()][cols])) == 0 and np.all(va["final_lane"][()][cols] == lane[0, 0])
    print(f"lane {int(lane[0, 0])}: {checked} values over {len(names)} vehicle columns and 4 trajectory arrays")


def lane_counts(path):
    f = h5py.File(path, "r")
    lane = f["trajectories/lane"][()]
    n_lanes = int(f["meta/lanes"][()]) if "meta/lanes" in f else int(lane.max()) + 1
    return f, lane, np.stack([(lane == l).sum(axis=1) for l in range(max(n_lanes, 2))], axis=1)


def equalise(path, tol):
    f, lane, n = lane_counts(path)
    last = n[2 * len(n) // 3:]
    worst = int(np.max(np.abs(last[:, 0] - last[:, 1])))
    changes = int(f["vehicles/lane_changes"][()].sum())
    assert worst <= int(tol), f"|n0 - n1| reaches {worst} over the last third (start {n[0].tolist()})"
    assert changes > 0, "no lane changes"
    print(f"start {n[0].tolist()}, last third |n0 - n1| <= {worst}, {changes} lane changes")


def lane_share(path, op, share):
    f, lane, n = lane_counts(path)
    half = n[len(n) // 2:, 0].astype(float)
    total = lane.shape[1]
    m = float(half.mean())
    ok = m > float(share) * total if op == "gt" else m <= float(share) * total
    changes = int(f["vehicles/lane_changes"][()].sum())
    assert ok, f"lane 0 holds {m:.2f} of {total} on average over the second half (want {op} {float(share) * total:g})"
    print(f"lane 0 holds {m:.2f} of {total} vehicles on average over the second half (start {n[0].tolist()}, "
          f"{changes} lane changes)")


def identical(pa, pb):
    a, b = h5py.File(pa, "r"), h5py.File(pb, "r")
    skip = {"meta/wall_time_s", "meta/start_time", "meta/threads", "meta/phase_time"}
    oa, ob = datasets(a), datasets(b)
    assert set(oa) == set(ob), sorted(set(oa) ^ set(ob))
    bad = [k for k in oa if k not in skip and raw(oa[k][()]) != raw(ob[k][()])]
    assert not bad, bad
    changes = int(a["vehicles/lane_changes"][()].sum()) if "vehicles/lane_changes" in a else 0
    assert changes > 0, "no lane changes: the comparison would not exercise them"
    print(f"{len(oa) - len(skip & set(oa))} datasets equal, {changes} lane changes")


def physical(path):
    f = h5py.File(path, "r")
    tr, ve = f["trajectories"], f["vehicles"]
    x, lane = tr["x"][()], tr["lane"][()].astype(np.int64)
    L = float(f["meta/road_length"][()])
    length = ve["length"][()]
    n_frames, n = x.shape
    dt = float(f["meta/dt"][()])
    t = tr["t"][()]
    assert np.allclose(np.diff(t), dt, rtol=0, atol=1e-9 * t[-1]), "frames are not written every step"
    assert np.all(lane >= 0) and np.all(lane == np.round(lane)), "lane values"
    assert np.all(np.isfinite(x)), "non-finite positions"
    min_gap = np.inf
    frame_gaps = []
    for k in range(n_frames):
        all_gaps = []
        for l in np.unique(lane[k]):
            ids = np.nonzero(lane[k] == l)[0]
            p = np.mod(x[k, ids], L)
            order = np.argsort(p, kind="stable")
            ps, ids = p[order], ids[order]
            # the gap of each vehicle to the next one around the ring in its lane (itself a lap ahead when alone)
            gaps = (np.roll(ps, -1) - ps) % L
            gaps[gaps == 0] = L if len(ps) == 1 else 0.0
            gaps = gaps - length[np.roll(ids, -1)]
            assert np.all(gaps > 0), f"frame {k} (t = {t[k]:g} s) lane {l}: gap {gaps.min():g} m"
            min_gap = min(min_gap, float(gaps.min()))
            all_gaps.append(gaps)
        all_gaps = np.concatenate(all_gaps)
        frame_gaps.append((all_gaps.min(), all_gaps.mean()))
    assert np.all(lane.shape[1] == n), "vehicle count"
    jumps = np.abs(np.diff(lane, axis=0))
    assert np.all(jumps <= 1), "a vehicle moved more than one lane in a step"
    seen = int(jumps.sum())
    counted = int(ve["lane_changes"][()].sum())
    per_vehicle = jumps.sum(axis=0)
    assert np.array_equal(per_vehicle, ve["lane_changes"][()]), "per-vehicle lane changes differ from the frames"
    assert np.array_equal(lane[-1], ve["final_lane"][()]), "final_lane differs from the last frame"
    assert counted == seen and counted > 0, (counted, seen)
    cut = int(ve["cut_ins"][()].sum())
    assert 0 <= cut <= counted, (cut, counted)
    assert int(f["summary/overlaps"][()]) == 0, "overlaps repaired"
    # no change at the final instant: the last frame's lanes are the previous frame's
    assert np.array_equal(lane[-1], lane[-2]), "lanes changed at the final instant"
    # x, v and a move with their vehicle through the changes: the ballistic update of each vehicle holds from frame
    # to frame (where it does not stop), up to whole laps: a vehicle entering a lane takes the lap of that lane's
    # positions (src/core/lanes.c, new_order), so x may move by a multiple of L at a change, and only then
    v, a = tr["v"][()], tr["a"][()]
    assert f["meta/integrator"][()] in (b"ballistic", "ballistic"), f["meta/integrator"][()]
    moving = v[1:] > 0
    ev = np.abs(v[1:] - v[:-1] - a[:-1] * dt)[moving]
    step = x[1:] - x[:-1]
    ex = step - v[:-1] * dt - 0.5 * a[:-1] * dt * dt
    laps = np.round(ex / L)
    res = np.abs(ex - laps * L)[moving]
    scale = max(1.0, float(np.abs(x).max()))
    assert ev.max() < 1e-9 and res.max() < 1e-9 * scale, (ev.max(), res.max())
    jumps_at = laps != 0
    assert not np.any(jumps_at & (np.diff(lane, axis=0) == 0)), "x moved by a lap without a lane change"
    n_lap_jumps = int(jumps_at.sum())
    assert np.array_equal(ve["final_x"][()], x[-1]) and np.array_equal(ve["final_v"][()], v[-1]), "final state"
    # the distance of the statistics window: the frames' increments without the lap moves
    warm = int(np.argmin(np.abs(t - float(f["meta/warmup"][()]))))
    dist = np.sum((step - laps * L)[warm:], axis=0)
    dist_err = float(np.max(np.abs(ve["distance"][()] - dist)))
    assert dist_err < 1e-6, f"distance differs from the frames by {dist_err} m"
    # the records at the frames' instants: the fleet's speeds and the lanes' gaps
    ts = f["timeseries"]
    rt = ts["t"][()]
    for j, tj in enumerate(rt):
        k = int(np.argmin(np.abs(t - tj)))
        if abs(t[k] - tj) > 1e-9 * max(1.0, tj):
            continue
        for name, want, tol in (("mean_speed", v[k].mean(), 1e-12), ("max_speed", v[k].max(), 0),
                                ("min_speed", v[k].min(), 0), ("min_gap", frame_gaps[k][0], 1e-12 * scale),
                                ("mean_gap", frame_gaps[k][1], 1e-12 * scale)):
            got = float(ts[name][j])
            assert abs(got - want) <= tol * max(1.0, abs(want)), f"t = {tj:g}: {name} {got} != {want}"
    print(f"{n_frames} frames x {n} vehicles: least gap {min_gap:.3f} m, {counted} lane changes seen in the frames "
          f"and counted, {cut} cut-ins, {n_lap_jumps} changes moving x by a lap")


if __name__ == "__main__":
    cmd, args = sys.argv[1], sys.argv[2:]
    try:
        {"same_lane": same_lane, "equalise": equalise, "lane_share": lane_share, "identical": identical,
         "physical": physical}[cmd](*args)
    except AssertionError as e:
        print(f"{cmd}: {e}")
        sys.exit(1)
