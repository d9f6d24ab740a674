"""Every column a corridor result derives from its vehicles (/timeseries, /trips, /detectors, /edie, /summary),
recomputed with numpy from the trajectory points written at every step, by the definitions of docs/corridors.md
and docs/metrics.md.

usage: corridor.py BIN TRAJ.h5 [OTHER.h5 ...] TMPDIR
TRAJ.h5 has a trajectory frame every step; each OTHER.h5 is the same scenario run without trajectories.
The scenario must be flat (the energy model is evaluated at theta = 0) and its demand must end early enough that no
vehicle is still queued at the end (the arrivals are then the trips' arrival times).

A step of a vehicle goes from its point at t to its point at t + dt; the step in which it leaves (front at or past
L, not in the trajectories) is predicted with the ballistic update from its last point and checked against the
trip's distance. Tolerances (the rest bit for bit):
- 1e-12 relative (or absolute, for values that are sums of terms of either sign or near 0) for sums the engine adds
  in another order: fuel and times over a trip's steps, rates over the vehicles on the road, Edie and detector sums,
  class and fleet totals; ratios of such sums inherit it (each sum has < 3e4 terms: n * 2^-53 < 4e-12 relative is
  the worst case for non-negative terms; observed errors are far smaller);
- the speed s.d. across vehicles: two-pass here and in the engine: 1e-12 relative plus 1e-12 * mean speed;
- gaps: 1e-9 m (positions < 1e4 m round at 2e-12 m);
- the predicted exit-step distance against the trip's distance: 1e-9 m (the engine adds the steps' increments)."""
import os
import sys

import h5py
import numpy as np
import yaml

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from common import compare, energy, hard_brake_onsets, open_run, report, stops, waves  # noqa: E402
import common  # noqa: E402

bin_path, f, others, tmp, (v_stop, v_go, hard, v_wave), dt, warm, L = open_run(sys.argv)
NAME = os.environ.get("RECOMPUTE_NAME", "corridor")  # prefix of the test names
traj_path = f.filename
scen = yaml.safe_load(f["meta/scenario_text"][()].decode())
dur = f["meta/duration"][()]
n_steps = int(round(dur / dt))
w0 = int(round(warm / dt))
rho = f["classes/fuel_density"][()]
cls_len = f["classes/length"][()]
n_cls = len(rho)
assert f["meta/integrator"][()].decode() == "ballistic" and "grade" not in scen["road"] and "elevation" not in scen["road"]

# Trajectory points, sorted by vehicle and time; the step index of each point.
P = {k: f["trajectories/" + k][()] for k in ("t", "serial", "x", "v", "a", "fuel_rate")}
P["k"] = np.rint(P["t"] / dt).astype(np.int64)
assert np.allclose(P["k"] * dt, P["t"], rtol=0, atol=1e-9)
order = np.lexsort((P["k"], P["serial"]))
P = {k: v[order] for k, v in P.items()}
ser = P["serial"].astype(np.int64)

# Trips by serial.
T = {k: f["trips/" + k][()] for k in f["trips"]}
n_trips = len(T["serial"])
by_serial = np.full(int(T["serial"].max()) + 1, -1)
by_serial[T["serial"].astype(np.int64)] = np.arange(n_trips)
assert (by_serial >= 0).all(), "a serial without a trip"
trip_of = by_serial[ser]
cid = T["class_id"].astype(np.int64)[trip_of]
length = cls_len[cid]
completed = T["completed"][trip_of] == 1

# The energy model at every point: the fuel rate written, and the infeasibility flag.
fr_model, flag = np.zeros(len(ser)), np.zeros(len(ser), dtype=int)
for c in range(n_cls):
    m = cid == c
    fr_model[m], flag[m] = energy(bin_path, f["classes/name"][c].decode(), P["v"][m], P["a"][m], np.zeros(m.sum()), tmp)
compare(f"{NAME}_traj_fuel_rate_is_the_class_model", P["fuel_rate"], fr_model, rtol=1e-13)

# Steps: point i to point i + 1 of the same vehicle one step later; a completed trip's last point to the predicted
# exit position. An unfinished trip's last point (t = duration) starts no step.
last = np.ones(len(ser), dtype=bool)
last[:-1] = ser[1:] != ser[:-1]
nxt = np.roll(P["x"], -1)
consecutive = ~last
assert (np.roll(P["k"], -1)[consecutive] == P["k"][consecutive] + 1).all(), "a vehicle misses a frame"
xv, vv, av = P["x"], P["v"], P["a"]
with np.errstate(divide="ignore", invalid="ignore"):
    x_pred = xv + np.where(vv + av * dt >= 0, vv * dt + 0.5 * av * dt * dt, -(vv * vv) / (2.0 * av))
steps = consecutive | (last & completed)
xb_all = np.where(consecutive, nxt, x_pred)
exit_pts = last & completed
report(f"{NAME}_exit_steps_reach_L", not (x_pred[exit_pts] >= L).all() or not (P["x"][exit_pts] < L).all())
S = {"k": P["k"][steps], "xa": xv[steps], "xb": xb_all[steps], "xp": x_pred[steps], "v": vv[steps], "a": av[steps],
     "fr": P["fuel_rate"][steps], "flag": flag[steps], "len": length[steps], "cls": cid[steps], "trip": trip_of[steps],
     "ser": ser[steps], "consecutive": consecutive[steps]}
# Road order within a step: front first = lowest serial first (no overtaking, FIFO entrance).
so = np.lexsort((S["ser"], S["k"]))
S = {k: v[so] for k, v in S.items()}
S_win = S["k"] >= w0
# Overlap repairs (docs/corridors.md): a vehicle whose ballistic step would end past its leader's rear (the leader
# after its own step, repaired or not, exits included) is put at gap 0 and stopped. The front vehicle follows a
# virtual leader 1e5 m ahead (free outflow): no repair.
has_lead = np.concatenate([[False], S["k"][1:] == S["k"][:-1]])
lead_rear = np.concatenate([[np.inf], S["xb"][:-1] - S["len"][:-1]])
ov = has_lead & (S["xp"] > lead_rear)
report(f"{NAME}_overlap_repairs", not (np.abs(S["xb"][ov] - lead_rear[ov]) <= 1e-9).all(),
       "a vehicle predicted to overlap was not left at gap 0")
# Every other step is the ballistic update (docs/scenarios.md); the exit steps were predicted with it.
ok_ = S["consecutive"] & ~ov
compare(f"{NAME}_traj_steps_are_ballistic", S["xb"][ok_], S["xp"][ok_], 0, 1e-9)
ov_per_step = np.bincount(S["k"][ov], minlength=n_steps + 1)

# ---- /trips
first = np.ones(len(ser), dtype=bool)
first[1:] = ser[1:] != ser[:-1]
trip_rows = trip_of[first]
want = {k: np.full(n_trips, np.nan) for k in ("entry_time", "entry_speed", "exit_time", "fuel", "distance",
                                              "time_stopped", "stops", "hard_brakes", "infeasible_steps")}
want["entry_time"][trip_rows] = P["t"][first]
want["entry_speed"][trip_rows] = P["v"][first]
done = trip_of[exit_pts]
want["exit_time"][done] = (P["k"][exit_pts] + 1) * dt
dist_pred = np.zeros(n_trips)
np.add.at(dist_pred, S["trip"], S["xb"] - S["xa"])
fuel_t = np.zeros(n_trips)
np.add.at(fuel_t, S["trip"], S["fr"] * dt)
want["fuel"], want["distance"] = fuel_t, dist_pred
stopped_t = np.zeros(n_trips)
np.add.at(stopped_t, S["trip"], np.where(S["v"] < v_stop, dt, 0.0))
want["time_stopped"] = stopped_t
infeas_t = np.zeros(n_trips)
np.add.at(infeas_t, S["trip"], S["flag"] == 1)
want["infeasible_steps"] = infeas_t
# Event counters per trip, over the trip's own steps (plain loops, docs/metrics.md).
w_stops = np.zeros(n_trips)
w_hard = np.zeros(n_trips)
start_of = {int(t): i for t, i in zip(trip_of[first], np.where(first)[0])}
for tr in range(n_trips):
    i0 = start_of[tr]
    i1 = i0
    while i1 + 1 < len(ser) and ser[i1 + 1] == ser[i0]:
        i1 += 1
    k0 = P["k"][i0]
    n_st = (i1 - i0) + (1 if completed[i0] else 0)          # steps of this trip
    # speeds at the starts of the steps and after the last one (the exit step: the ballistic speed)
    vend = max(vv[i1] + av[i1] * dt, 0.0) if completed[i0] else None
    vs = np.array(list(vv[i0:i1 + 1]) + ([vend] if completed[i0] else []))
    ks = k0 + np.arange(n_st)
    want["stops"][tr] = stops(vs, vs[0] > v_go, np.ones(n_st, dtype=int), v_stop, v_go)
    w_stops[tr] = stops(vs, vs[0] > v_go, (ks >= w0).astype(int), v_stop, v_go)
    a_tr = av[i0:i0 + n_st][:, None]
    want["hard_brakes"][tr] = hard_brake_onsets(a_tr, np.ones(n_st, dtype=bool), hard)[0]
    w_hard[tr] = hard_brake_onsets(a_tr, ks >= w0, hard)[0]
compare(f"{NAME}_trip_distance_vs_predicted_exit", T["distance"], dist_pred, rtol=0, atol=1e-9)
want["travel_time"] = want["exit_time"] - want["entry_time"]
want["queue_delay"] = want["entry_time"] - T["arrival_time"]
tol_trip = {"fuel": (1e-12, 0), "distance": (1e-12, 1e-9), "time_stopped": (0, 1e-12 * n_steps * dt)}
events = {"stops": want["stops"].sum(), "hard brakes": want["hard_brakes"].sum(), "exits": done.size,
          "delayed entries": (want["queue_delay"] > 0.5 * dt).sum(), "infeasible steps": want["infeasible_steps"].sum(),
          "unfinished trips": n_trips - done.size}
report(f"{NAME}_has_events", min(events.values()) <= 0, f"the scenario no longer exercises all of {events}")

# ---- /timeseries: the vehicles on the road at each record instant, front first.
ts_t = f["timeseries/t"][()]
rk = np.rint(ts_t / dt).astype(np.int64)
rows = {k: np.full(len(rk), np.nan) for k in ("vehicles", "mean_speed", "sd_speed", "min_speed", "max_speed",
                                              "frac_stopped", "waves", "fuel_rate", "mean_gap", "min_gap")}
cls_rate = np.zeros((len(rk), n_cls))
po = np.lexsort((ser, P["k"]))
pk, px, pv, pfr, plen, pcls = (a[po] for a in (P["k"], xv, vv, P["fuel_rate"], length, cid))
for r, k in enumerate(rk):
    lo, hi = np.searchsorted(pk, k), np.searchsorted(pk, k + 1)
    n = hi - lo
    rows["vehicles"][r] = n
    rows["frac_stopped"][r] = (pv[lo:hi] < v_stop).sum() / n if n else 0.0
    rows["waves"][r] = waves(pv[lo:hi] < v_wave, circular=False)
    rows["fuel_rate"][r] = pfr[lo:hi].sum()
    for c in range(n_cls):
        cls_rate[r, c] = pfr[lo:hi][pcls[lo:hi] == c].sum()
    if n:
        v = pv[lo:hi]
        rows["mean_speed"][r], rows["sd_speed"][r] = v.mean(), v.std()
        rows["min_speed"][r], rows["max_speed"][r] = v.min(), v.max()
    if n > 1:
        g = px[lo:hi - 1] - plen[lo:hi - 1] - px[lo + 1:hi]
        rows["mean_gap"][r], rows["min_gap"][r] = g.mean(), g.min()
rows["class_fuel_rate"] = cls_rate
entry_t, exit_t, arr_t = want["entry_time"], want["exit_time"], T["arrival_time"]
rows["entered"] = (entry_t[None, :] <= ts_t[:, None] + 1e-9).sum(axis=1)
rows["exited"] = (exit_t[None, :] <= ts_t[:, None] + 1e-9).sum(axis=1)
rows["arrived"] = (arr_t[None, :] <= ts_t[:, None] + 1e-9).sum(axis=1)
rows["queued"] = rows["arrived"] - rows["entered"]
rows["delayed"] = ((entry_t[None, :] <= ts_t[:, None] + 1e-9) & (want["queue_delay"] > 0.5 * dt)[None, :]).sum(axis=1)
report(f"{NAME}_records_conserve", not ((rows["entered"] == rows["exited"] + rows["vehicles"]).all()))

rows["overlaps"] = np.concatenate([[0], np.cumsum(ov_per_step)])[rk]   # repairs in the steps before the record

# ---- Edie cells and detectors from the steps.
xe, te = f["edie/x_edges"][()], f["edie/t_edges"][()]
nx, nt = len(xe) - 1, len(te) - 1
edie_every = int(round((te[1] - te[0]) / dt))
Ed, Et, Ef = np.zeros((nt, nx)), np.zeros((nt, nx)), np.zeros((nt, nx))
Cd, Cf = np.zeros((n_cls, nx)), np.zeros((n_cls, nx))
j = S["k"] // edie_every
span = S["xb"] - S["xa"]
moving = span > 0
lo_x, hi_x = np.maximum(S["xa"], 0.0), np.minimum(S["xb"], L)
cell = np.minimum(np.searchsorted(xe, lo_x, side="right") - 1, nx - 1)
dtot = np.zeros(len(span))
for part in range(3):  # a step crosses at most two cell edges (dx >> the longest step)
    c_ok = moving & (lo_x < hi_x) & (cell < nx)
    edge = xe[np.minimum(cell + 1, nx)]
    b = np.minimum(edge, hi_x)
    d = np.where(c_ok, b - lo_x, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.where(c_ok, d / span, 0.0)
    ci = np.where(c_ok, cell, 0)
    np.add.at(Ed, (j, ci), d)
    np.add.at(Et, (j, ci), dt * w)
    np.add.at(Ef, (j, ci), S["fr"] * dt * w)
    np.add.at(Cd, (S["cls"], ci), np.where(S_win, d, 0.0))
    np.add.at(Cf, (S["cls"], ci), np.where(S_win, S["fr"] * dt * w, 0.0))
    dtot += d
    lo_x, cell = np.where(c_ok, b, lo_x), np.where(c_ok, cell + 1, cell)
report(f"{NAME}_edie_split_complete", not np.allclose(dtot[moving], (np.minimum(S["xb"], L) - np.maximum(S["xa"], 0))[moving],
                                                        rtol=0, atol=1e-9))
still = ~moving & (S["xa"] >= 0) & (S["xa"] < L)
ci = np.minimum(np.searchsorted(xe, S["xa"], side="right") - 1, nx - 1)
np.add.at(Et, (j[still], ci[still]), dt)
np.add.at(Ef, (j[still], ci[still]), S["fr"][still] * dt)
np.add.at(Cf, (S["cls"][still & S_win], ci[still & S_win]), S["fr"][still & S_win] * dt)
area = np.diff(te)[:, None] * np.diff(xe)[None, :]              # s * m
with np.errstate(divide="ignore", invalid="ignore"):
    edie = {"distance": Ed, "time": Et, "fuel_mass": Ef,
            "flow": Ed / area * 3600.0, "density": Et / area * 1000.0, "speed": np.where(Et > 0, Ed / Et, np.nan),
            "fuel": Ef / (area / 3.6e6),
            "class_distance": Cd, "class_fuel": Cf,
            "class_fuel_per_km": np.where(Cd > 0, Cf / (Cd / 1000.0), np.nan),
            "grade": np.zeros(nx)}

dx_det = f["detectors/x"][()]
d_t0, d_t1 = f["detectors/t_start"][()], f["detectors/t_end"][()]
det_every = int(round((d_t1[0] - d_t0[0]) / dt))
jd = S["k"] // det_every
nint = len(d_t0)
cnt, sv, sinv, occ = (np.zeros((nint, len(dx_det))) for _ in range(4))
for q, xd in enumerate(dx_det):
    pas = (S["xa"] <= xd) & (xd < S["xb"])
    vpass = (S["xb"] - S["xa"])[pas] / dt
    np.add.at(cnt[:, q], jd[pas], 1)
    np.add.at(sv[:, q], jd[pas], vpass)
    np.add.at(sinv[:, q], jd[pas], 1.0 / vpass)
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = np.maximum((xd - S["xa"]) / span * dt, 0.0)
        t1 = np.minimum((xd + S["len"] - S["xa"]) / span * dt, dt)
    o = np.where(moving, np.maximum(t1 - t0, 0.0), np.where((S["xa"] >= xd) & (S["xa"] - S["len"] <= xd), dt, 0.0))
    np.add.at(occ[:, q], jd, o)
ilen = (d_t1 - d_t0)[:, None]
with np.errstate(divide="ignore", invalid="ignore"):
    det = {"count": cnt, "flow": cnt / ilen * 3600.0, "speed_time_mean": np.where(cnt > 0, sv / cnt, np.nan),
           "speed_harmonic_mean": np.where(cnt > 0, cnt / sinv, np.nan), "occupancy": occ / ilen}
report(f"{NAME}_detectors_see_passages", not (cnt.sum(axis=0) > 0).all(),
       f"every detector must count passages (the last one close to L counts exit steps): {cnt.sum(axis=0)}")

# ---- /summary over the window.
wf = np.zeros(n_trips)
wd = np.zeros(n_trips)
ws = np.zeros(n_trips)
wst = np.zeros(n_trips)
wi = np.zeros(n_trips)
np.add.at(wf, S["trip"][S_win], S["fr"][S_win] * dt)
np.add.at(wd, S["trip"][S_win], span[S_win])
np.add.at(ws, S["trip"][S_win], 1)
np.add.at(wst, S["trip"][S_win], np.where(S["v"][S_win] < v_stop, dt, 0.0))
np.add.at(wi, S["trip"][S_win], S["flag"][S_win] == 1)
tc = T["class_id"].astype(np.int64)
cf = np.array([wf[tc == c].sum() for c in range(n_cls)])
cd = np.array([wd[tc == c].sum() for c in range(n_cls)])
csteps = np.array([ws[tc == c].sum() for c in range(n_cls)])
cstops = np.array([w_stops[tc == c].sum() for c in range(n_cls)])
cinf = np.array([wi[tc == c].sum() for c in range(n_cls)])
ctrips = np.array([((T["completed"] == 1) & (tc == c)).sum() for c in range(n_cls)])
dist, vht_s = cd.sum(), csteps.sum() * dt
W = (n_steps - w0) * dt
litres = (cf / rho).sum()
done_m = T["completed"] == 1
rec_w = (rk >= w0) & (rows["vehicles"] > 0)
with np.errstate(divide="ignore", invalid="ignore"):
    summ = {
        "fuel": cf.sum(), "distance": dist, "vkt": dist / 1000, "vht": vht_s / 3600, "window": W,
        "l_per_100km": litres / (dist / 1e5), "mpg": (dist / 1609.344) / (litres / 3.785411784),
        "stops_per_vkm": w_stops.sum() / (dist / 1000), "hard_brakes_per_vkm": w_hard.sum() / (dist / 1000),
        "mean_speed": dist / vht_s, "sd_speed_time_avg": rows["sd_speed"][rec_w].mean(),
        "inflow": ((entry_t >= w0 * dt - 1e-9)).sum() / W * 3600,
        "outflow": ((exit_t >= (w0 + 1) * dt - 1e-9)).sum() / W * 3600,
        "infeasible_share": cinf.sum() / csteps.sum(), "time_stopped_share": wst.sum() / vht_s,
        "trips": done_m.sum(), "arrived": n_trips, "entered": n_trips, "exited": done_m.sum(),
        "on_road": (~done_m).sum(), "queued": 0, "overlaps": ov.sum(),
        "delayed": (want["queue_delay"] > 0.5 * dt).sum(),
        "mean_travel_time": want["travel_time"][done_m].mean(), "mean_trip_fuel": fuel_t[done_m].mean(),
        "mean_queue_delay": want["queue_delay"].mean(),
        "class_fuel": cf, "class_distance": cd, "class_entered": np.bincount(tc, minlength=n_cls),
        "class_trips": ctrips,
        "class_l_per_100km": cf / rho / (cd / 1e5), "class_mpg": (cd / 1609.344) / (cf / rho / 3.785411784),
        "class_stops_per_vkm": cstops / (cd / 1000), "class_infeasible_share": cinf / csteps,
        "class_trip_fuel_mean": np.array([fuel_t[done_m & (tc == c)].mean() for c in range(n_cls)]),
        "class_trip_time_mean": np.array([want["travel_time"][done_m & (tc == c)].mean() for c in range(n_cls)]),
        "class_g_per_km_flat": Cf.sum(axis=1) / (Cd.sum(axis=1) / 1000),
        "class_g_per_km_up": np.full(n_cls, np.nan), "class_g_per_km_down": np.full(n_cls, np.nan),
    }
SUM = 1e-12
exact = {"trips", "arrived", "entered", "exited", "on_road", "queued", "overlaps", "delayed", "class_entered",
         "class_trips", "window"}


def check(path, tag):
    r = h5py.File(path)
    for k, v in want.items():
        rt, at = tol_trip.get(k, (0, 0))
        compare(f"{tag}_trips_{k}", r["trips/" + k][()], v, rt, at)
    for k, v in rows.items():
        rt, at = (0, 0)
        if k in ("mean_speed", "fuel_rate", "class_fuel_rate"):
            rt = SUM
        if k == "sd_speed":
            rt, at = SUM, SUM * np.nan_to_num(rows["mean_speed"])
        if k in ("mean_gap", "min_gap"):
            rt, at = SUM, 1e-9
        compare(f"{tag}_timeseries_{k}", r["timeseries/" + k][()], v, rt, at)
    for k, v in edie.items():
        compare(f"{tag}_edie_{k}", r["edie/" + k][()], v, SUM, SUM * np.nanmax(np.abs(v)) if np.isfinite(v).any() else 0)
    for k, v in det.items():
        compare(f"{tag}_detectors_{k}", r["detectors/" + k][()], v, SUM, SUM * np.nanmax(np.abs(v)))
    for k, v in summ.items():
        compare(f"{tag}_summary_{k}", r["summary/" + k][()], v, 0 if k in exact else SUM)


check(traj_path, f"{NAME}_traj")
for i, p in enumerate(others):
    check(p, f"{NAME}_notraj{i}" if len(others) > 1 else f"{NAME}_notraj")
sys.exit(1 if common.failures else 0)
