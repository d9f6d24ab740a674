"""Checks of multi-lane ring results for tests/t_lanes.sh, one subcommand per check; each exits non-zero with the
reason on failure and prints a one-line account of what it measured on success.

  same_lane MULTI.h5 SINGLE.h5 FIRST N   vehicles FIRST..FIRST+N-1 of MULTI equal vehicles 0..N-1 of SINGLE, bit for bit
  equalise FILE.h5 TOL                   lane counts of a 2-lane ring within TOL of each other over the last third
  lane_share FILE.h5 OP SHARE            lane 0's mean count over the second half, compared (gt/le) with SHARE * N
  identical A.h5 B.h5                    every dataset equal bit for bit (meta wall times, threads left out)
  physical FILE.h5 [STEPS,...]           per-frame lane order, positive gaps, conservation, counted lane changes,
                                         each vehicle's ballistic update across its changes
  mobil_replay FILE.h5 RULE              every step's lane changes against MOBIL recomputed here (all-IDM rings)
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


def v_stop_of(f):
    """statistics.v_stop_mps of the run (its scenario text, or the default 0.5 m/s)."""
    import re
    text = f["meta/scenario_text"][()]
    text = text.decode() if isinstance(text, bytes) else str(text)
    m = re.search(r"v_stop_mps:\s*([0-9.eE+-]+)", text)
    return float(m.group(1)) if m else 0.5


def lane_rates(la, lane_of_step, n_lanes, dt, rec_steps, v_stop):
    """/lanes/lane_cut_in_rate and /lanes/frac_stopped against the frames: each lane's vehicle-seconds over the
    steps stepped (the vehicles of each step's frame, after that step's changes), and at each record the share of each
    lane's vehicles slower than v_stop. lane_of_step: per stepped step, its frame's lanes; rec_steps: per record, its
    frame's lanes and speeds. Returns an account."""
    vs = np.zeros(n_lanes)
    for l_k in lane_of_step:
        vs += np.bincount(l_k, minlength=n_lanes) * dt
    want = np.where(vs > 0, la["lane_cut_ins"][()] / np.where(vs > 0, vs, 1.0) * 3600.0, 0.0)
    got = la["lane_cut_in_rate"][()]
    assert np.allclose(got, want, rtol=1e-12, atol=0), f"/lanes/lane_cut_in_rate {got} != {want} from the frames"
    fs = la["frac_stopped"][()]
    for j, (l_k, v_k) in enumerate(zip(rec_steps[0], rec_steps[1])):
        for l in range(n_lanes):
            m = l_k == l
            w = np.mean(v_k[m] < v_stop) if m.any() else np.nan
            assert (np.isnan(w) and np.isnan(fs[j, l])) or abs(fs[j, l] - w) <= 1e-15, \
                f"record {j} lane {l}: /lanes/frac_stopped {fs[j, l]} != {w} from the frame"
    return f"lane cut-in rates {np.round(got, 3).tolist()} /h and {fs.size} frac_stopped values match the frames"


def physical(path, min_steps=None):
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
    # lane l starts with the vehicles after those of lanes 0..l-1 (fleet.lane_counts)
    assert np.all(np.diff(lane[0]) >= 0), "the first frame's lanes are not in vehicle order"
    # min_interval_s: a vehicle of group g changes again min_steps[g] steps after a change at the earliest
    if min_steps is not None:
        want = [int(s) for s in min_steps.split(",")]
        gid = ve["group_id"][()]
        for g, w in enumerate(want):
            gaps_steps = [np.diff(np.nonzero(jumps[:, i])[0]) for i in np.nonzero(gid == g)[0]]
            gaps_steps = np.concatenate([s for s in gaps_steps if len(s)] or [np.array([w], dtype=np.int64)])
            assert gaps_steps.min() >= w, f"group {g}: changes {gaps_steps.min()} steps apart (least {w})"
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
    # /lanes/lane_cut_in_rate and /lanes/frac_stopped from the frames (every frame but the final instant is stepped)
    la = f["lanes"]
    n_lanes = la["vehicles"].shape[1]
    rec = [int(np.argmin(np.abs(t - tj))) for tj in la["t"][()]]
    rates = lane_rates(la, [lane[k] for k in range(n_frames - 1)], n_lanes, dt,
                       ([lane[k] for k in rec], [v[k] for k in rec]), v_stop_of(f))
    print(f"{n_frames} frames x {n} vehicles: least gap {min_gap:.3f} m, {counted} lane changes seen in the frames "
          f"and counted, {cut} cut-ins, {n_lap_jumps} changes moving x by a lap; {rates}")


def idm(gap, v, vl, v0=30.0, T=1.0, s0=2.0, am=1.0, b=1.5):
    """IDM (Treiber, Hennecke & Helbing 2000) with wavefuel's defaults; docs/models.md."""
    s_star = s0 + max(0.0, v * T + v * (v - vl) / (2.0 * np.sqrt(am * b)))
    return am * (1.0 - (v / v0) ** 4 - (s_star / max(gap, 1e-3)) ** 2)


def mobil_replay(path, rule, p=0.2, th=0.1, bias=0.3, b_safe=4.0, interval=10):
    """Every step's lane changes of an all-IDM ring (default parameters, frames every step) recomputed here from
    MOBIL as Kesting, Treiber & Helbing (2007) state it, with the engine's documented protocol: decisions from the
    state at the step's start (frame k's positions and speeds, frame k-1's lanes), accelerations before noise, the
    larger positive advantage of the two sides (the right one at a tie), no vehicle twice within `interval` steps,
    one vehicle per target gap (the larger advantage). Decisions within 1e-9 m/s^2 of a boundary are not judged."""
    f = h5py.File(path, "r")
    tr, ve = f["trajectories"], f["vehicles"]
    x, v, lane = tr["x"][()], tr["v"][()], tr["lane"][()].astype(np.int64)
    L = float(f["meta/road_length"][()])
    length = ve["length"][()]
    n_frames, n = x.shape
    n_lanes = int(lane.max()) + 1
    ready = np.zeros(n, dtype=np.int64)
    p, th, bias, b_safe, interval = float(p), float(th), float(bias), float(b_safe), int(interval)
    fwd = lambda a, b: (b - a) % L
    agree = unsure = 0
    for k in range(1, n_frames - 1):
        pos, vel, ln = np.mod(x[k], L), v[k], lane[k - 1]
        # each lane's vehicles in the order of their positions around the ring
        order = {}
        for l in range(n_lanes):
            ids = np.nonzero(ln == l)[0]
            order[l] = ids[np.argsort(pos[ids], kind="stable")]

        def leader_in(l, i):  # index in order[l] of the first vehicle at or ahead of i's position
            q = order[l]
            j = int(np.searchsorted(pos[q], pos[i], side="left"))
            return j % len(q)

        best_dir, best_adv, best_key, close = np.zeros(n, dtype=np.int64), np.zeros(n), {}, False
        for i in range(n):
            if k < ready[i]:
                continue
            l = int(ln[i])
            q = order[l]
            ki = int(np.nonzero(q == i)[0][0])
            nl = len(q)
            ld = q[(ki + 1) % nl]
            own_gap = L - length[i] if nl == 1 else fwd(pos[i], pos[ld]) - length[ld]
            own_now = idm(own_gap, vel[i], vel[ld])
            for d in (-1, 1):
                m = l + d
                if m < 0 or m >= n_lanes:
                    continue
                qm = order[m]
                has_new = len(qm) > 0
                if not has_new:
                    own_new = idm(L - length[i], vel[i], vel[i])
                else:
                    jg = leader_in(m, i)
                    g, fo = qm[jg], qm[jg - 1]
                    gap_new = fwd(pos[i], pos[g]) - length[g]
                    gap_fo_new = fwd(pos[fo], pos[i]) - length[i]
                    if not (gap_new > 0 and gap_fo_new > 0):
                        continue
                    own_new = idm(gap_new, vel[i], vel[g])
                    gap_fo_now = L - length[g] if len(qm) == 1 else fwd(pos[fo], pos[g]) - length[g]
                    new_now = idm(gap_fo_now, vel[fo], vel[g])
                    new_new = idm(gap_fo_new, vel[fo], vel[i])
                if own_new < -b_safe or (has_new and new_new < -b_safe):
                    if min(abs(own_new + b_safe), abs(new_new + b_safe) if has_new else 1.0) < 1e-9:
                        close = True
                    continue
                dn = new_new - new_now if has_new else 0.0
                do = 0.0
                if nl >= 2:
                    o = q[ki - 1]
                    old_now = idm(fwd(pos[o], pos[i]) - length[i], vel[o], vel[i])
                    old_new = idm(L - length[o], vel[o], vel[o]) if nl == 2 else \
                        idm(fwd(pos[o], pos[ld]) - length[ld], vel[o], vel[ld])
                    do = old_new - old_now
                own = own_new - own_now
                if rule == "symmetric":
                    a = own + p * (dn + do) - th
                elif d > 0:
                    a = own + p * dn - (th + bias)
                else:
                    a = own + p * do - (th - bias)
                if abs(a) < 1e-9 or abs(a - best_adv[i]) < 1e-9 and best_dir[i]:
                    close = True
                if a > best_adv[i]:
                    best_adv[i], best_dir[i] = a, d
                    best_key[i] = (m, int(qm[jg]) if has_new else -1)
        # one vehicle per target gap: the larger advantage
        claims = {}
        for i in np.nonzero(best_dir)[0]:
            key = best_key[i]
            if key not in claims or best_adv[i] > best_adv[claims[key]]:
                claims[key] = i
        want = np.zeros(n, dtype=np.int64)
        for i in claims.values():
            want[i] = best_dir[i]
        got = lane[k] - lane[k - 1]
        if not np.array_equal(want, got):
            if close:
                unsure += 1
                # follow the engine from here on
            else:
                bad = np.nonzero(want != got)[0]
                raise AssertionError(f"step {k} (t = {tr['t'][k]:g} s): vehicles {bad.tolist()} change by "
                                     f"{got[bad].tolist()}, MOBIL says {want[bad].tolist()} "
                                     f"(advantages {best_adv[bad].round(6).tolist()})")
        else:
            agree += 1
        ready[got != 0] = k + interval
    total = int(np.abs(np.diff(lane, axis=0)).sum())
    assert total > 0, "no lane changes to check"
    assert unsure <= (n_frames - 2) // 100, f"{unsure} steps too close to a boundary to judge"
    print(f"{agree} steps of {n_frames - 2} agree with MOBIL recomputed here ({total} changes), {unsure} too close to "
          f"call")


if __name__ == "__main__":
    cmd, args = sys.argv[1], sys.argv[2:]
    try:
        {"same_lane": same_lane, "equalise": equalise, "lane_share": lane_share, "identical": identical,
         "physical": physical, "mobil_replay": mobil_replay}[cmd](*args)
    except AssertionError as e:
        print(f"{cmd}: {e}")
        sys.exit(1)
