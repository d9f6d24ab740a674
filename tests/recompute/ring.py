"""Every column a ring result derives from its vehicles (/timeseries, /vehicles, /summary and their per-class
arrays), recomputed from the trajectories written at every step with numpy, by the definitions of docs/metrics.md.

usage: ring.py BIN TRAJ.h5 [OTHER.h5 ...] TMPDIR
TRAJ.h5 has a trajectory frame every step; each OTHER.h5 is the same scenario run without trajectories (the fused
step), checked against the same recomputation.

Tolerances (the rest is compared bit for bit: extremes, counts, shares of counts, waves, positions and speeds):
- 1e-12 relative for sums that the engine adds in another order (fuel over <= 600 steps, rates over <= 600
  vehicles, distances over classes): every term is non-negative, so any order is within n * 2^-53 (< 7e-14)
  relative of the exact sum; ratios of such sums (L/100 km, mpg, mean speed, per-vkm rates) inherit it;
- the speed s.d. across vehicles: the engine combines 256-vehicle blocks' second moments (Chan et al.), here a
  two-pass variance: each within n * 2^-53 relative of the exact sum of squares, plus the rounding of the mean;
  1e-12 relative to the s.d. plus 1e-12 relative to the mean speed (a 1/(N-1) variance differs by 8e-4 relative);
- per-vehicle variances over time: the engine uses E[x^2] - E[x]^2 (cancellation), here a two-pass variance; they
  agree within a few n * 2^-53 * E[x^2]: 1e-12 * E[x^2] absolute;
- gaps: 1e-9 m absolute (the engine may compute them from positions reduced modulo L, which rounds at 2^-53 * L)."""
import sys

import h5py
import numpy as np

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from common import compare, energy, hard_brake_onsets, open_run, report, stops_all, waves  # noqa: E402
import common  # noqa: E402

bin_path, f, others, tmp, (v_stop, v_go, hard, v_wave), dt, warm, L = open_run(sys.argv)
traj_path = f.filename

T, X, V, A, FR = (f["trajectories/" + k][()] for k in ("t", "x", "v", "a", "fuel_rate"))
K = len(T) - 1                      # steps; frame k is the state at the start of step k
assert np.allclose(T, np.arange(K + 1) * dt, rtol=0, atol=1e-9), "trajectories are not written every step"
w0 = int(round(warm / dt))          # first step of the statistics window
win = np.arange(K) >= w0
W = (K - w0) * dt
N = X.shape[1]
cid = f["vehicles/class_id"][()]
length = f["vehicles/length"][()]
rho = f["classes/fuel_density"][()]
n_cls = len(rho)
assert N > 256, "the ring must span several 256-vehicle statistics blocks"

# The energy model at every step's (v, a), flat road: the fuel rate written to the trajectories, and the flag.
flag = np.zeros((K + 1, N), dtype=int)
fr_model = np.zeros((K + 1, N))
for c in range(n_cls):
    cols = np.where(cid == c)[0]
    fr_c, fl_c = energy(bin_path, f["classes/name"][c].decode(), V[:, cols].ravel(), A[:, cols].ravel(),
                        np.zeros(V[:, cols].size), tmp)
    fr_model[:, cols], flag[:, cols] = fr_c.reshape(K + 1, -1), fl_c.reshape(K + 1, -1)
compare("ring_traj_fuel_rate_is_the_class_model", FR, fr_model, rtol=1e-13)

# /timeseries at t = m * output_interval: frame m * stride.
ts_t = f["timeseries/t"][()]
frames = np.rint(ts_t / dt).astype(int)
assert np.allclose(frames * dt, ts_t, rtol=0, atol=1e-9) and frames[-1] == K
lead = np.roll(np.arange(N), -1)
gap = np.roll(X, -1, axis=1) - length[lead] - X
gap[:, -1] += L                     # the last vehicle's leader is vehicle 0, one lap ahead
Vr, Fr = V[frames], FR[frames]
ts = {
    "t": frames * dt,
    "mean_speed": Vr.mean(axis=1),
    "sd_speed": Vr.std(axis=1),
    "min_speed": Vr.min(axis=1),
    "max_speed": Vr.max(axis=1),
    "frac_stopped": (Vr < v_stop).sum(axis=1) / N,
    "waves": np.array([waves(row < v_wave, circular=True) for row in Vr]),
    "fuel_rate": Fr.sum(axis=1),
    "class_fuel_rate": np.stack([Fr[:, cid == c].sum(axis=1) for c in range(n_cls)], axis=1),
    "mean_gap": gap[frames].mean(axis=1),
    "min_gap": gap[frames].min(axis=1),
}
# Coverage of the wave count's boundaries: a slow run across the ring's end and across a block boundary.
# Every combination of slow and fast on both sides of each boundary must occur at some record.
slow = Vr < v_wave
combos = {f"{i}/{j} {s}{t}": int(((slow[:, i] == (s == "s")) & (slow[:, j] == (t == "s"))).sum())
          for i, j in ((N - 1, 0), (255, 256)) for s in "sf" for t in "sf"}
report("ring_waves_cover_boundaries", min(combos.values()) == 0 or not (ts["waves"] >= 2).any()
       or not (ts["waves"] == 1).any(), f"records per (follower/leader slow or fast): {combos}")
assert (gap >= 0).all()

# Overlap events (docs/metrics.md): a vehicle whose ballistic step would end past its leader's rear (the leader's
# position after the step, repaired or not) is put at gap 0 and stopped. Predicted here from each frame.
assert f["meta/integrator"][()].decode() == "ballistic"
with np.errstate(divide="ignore", invalid="ignore"):
    run_ = V[:K] + A[:K] * dt >= 0
    xp = X[:K] + np.where(run_, V[:K] * dt + 0.5 * A[:K] * dt * dt, -(V[:K] * V[:K]) / (2.0 * A[:K]))
lead_rear = np.roll(X[1:], -1, axis=1) - length[lead]
lead_rear[:, -1] += L
events = xp > lead_rear
report("ring_overlap_repairs", not (np.abs(gap[1:][events]) <= 1e-9).all() or not (V[1:][events] == 0).all(),
       "a vehicle predicted to overlap was not left at gap 0 and v = 0")
overlaps_so_far = np.concatenate([[0], np.cumsum(events.sum(axis=1))])
# Every other step is the ballistic update of docs/scenarios.md (Treiber & Kanagaraj 2015): x + v dt + a dt^2/2 and
# v + a dt, or, when v would turn negative within the step, x + v^2/(2|a|) and v = 0.
vp = np.where(run_, V[:K] + A[:K] * dt, 0.0)
compare("ring_traj_steps_are_ballistic_x", np.where(events, 0.0, X[1:]), np.where(events, 0.0, xp), 0, 1e-9)
compare("ring_traj_steps_are_ballistic_v", np.where(events, 0.0, V[1:]), np.where(events, 0.0, vp), 0, 1e-12)
report("ring_traj_has_stops_within_a_step", not (~run_ & (V[:K] > 0)).any(), "no vehicle stops within a step")

# /vehicles over the window.
cnt = win[:, None]
dist = X[K] - X[w0]
fuel = (FR[:K] * dt * cnt).sum(axis=0)
Vw, Aw = V[:K][win], A[:K][win]
veh = {
    "distance": dist,
    "fuel": fuel,
    "l_per_100km": np.divide(fuel / rho[cid], dist / 1e5, out=np.full(N, np.inf), where=dist > 0),
    "mpg": (dist / 1609.344) / (fuel / rho[cid] / 3.785411784),
    "stops": stops_all(V, win, v_stop, v_go),
    "time_stopped": ((V[:K] < v_stop) & cnt).sum(axis=0) * dt,
    "mean_speed": dist / W,
    "speed_var": Vw.var(axis=0),
    "accel_var": Aw.var(axis=0),
    "hard_brakes": hard_brake_onsets(A[:K], win, hard),
    "infeasible_steps": ((flag[:K] == 1) & cnt).sum(axis=0),
    "final_x": X[K],
    "final_v": V[K],
}
report("ring_lengths_are_the_class_lengths", not (length == f["classes/length"][()][cid]).all())

# /summary.
laps = np.floor(X[K] / L) - np.floor(X[w0] / L)
cls_fuel = np.array([fuel[cid == c].sum() for c in range(n_cls)])
cls_dist = np.array([dist[cid == c].sum() for c in range(n_cls)])
cls_n = np.array([(cid == c).sum() for c in range(n_cls)])
litres = (cls_fuel / rho).sum()
vkt = dist.sum() / 1000
rec_w = ts["t"] >= warm - 1e-9
summ = {
    "fuel": fuel.sum(), "distance": dist.sum(), "vkt": vkt, "window": W,
    "l_per_100km": litres / (dist.sum() / 1e5),
    "mpg": (dist.sum() / 1609.344) / (litres / 3.785411784),
    "stops_per_vkm": veh["stops"].sum() / vkt,
    "hard_brakes_per_vkm": veh["hard_brakes"].sum() / vkt,
    "mean_speed": dist.sum() / (N * W),
    "sd_speed_time_avg": ts["sd_speed"][rec_w].mean(),
    "throughput": laps.sum() / W * 3600,
    "infeasible_share": veh["infeasible_steps"].sum() / (N * (K - w0)),
    "time_stopped_share": veh["time_stopped"].sum() / (N * W),
    "overlaps": overlaps_so_far[K],
    "class_fuel": cls_fuel, "class_distance": cls_dist,
    "class_l_per_100km": cls_fuel / rho / (cls_dist / 1e5),
    "class_mpg": (cls_dist / 1609.344) / (cls_fuel / rho / 3.785411784),
    "class_infeasible_share": np.array([veh["infeasible_steps"][cid == c].sum() for c in range(n_cls)])
    / (cls_n * (K - w0)),
    "class_stops_per_vkm": np.array([veh["stops"][cid == c].sum() for c in range(n_cls)]) / (cls_dist / 1000),
}
events = {"stops": veh["stops"].sum(), "hard brakes": veh["hard_brakes"].sum(),
          "infeasible steps": veh["infeasible_steps"].sum(), "passages": laps.sum(), "overlaps": overlaps_so_far[K]}
report("ring_has_events", min(events.values()) <= 0, f"the scenario no longer exercises all of {events}")

SUM = 1e-12
tol_ts = {"mean_speed": (SUM, 0), "fuel_rate": (SUM, 0), "class_fuel_rate": (SUM, 0), "mean_gap": (SUM, 1e-9),
          "min_gap": (0, 1e-9)}
tol_veh = {"fuel": (SUM, 0), "l_per_100km": (SUM, 0), "mpg": (SUM, 0), "mean_speed": (SUM, 0)}
tol_sum = {k: (SUM, 0) for k in summ if k not in ("window", "overlaps", "throughput")}


def check(path, tag):
    r = h5py.File(path)
    for k, want in ts.items():
        rt, at = tol_ts.get(k, (0, 0))
        if k == "sd_speed":
            at = 1e-12 * ts["mean_speed"][:, None] if np.ndim(want) > 1 else 1e-12 * ts["mean_speed"]
            rt = 1e-12
        compare(f"{tag}_timeseries_{k}", r["timeseries/" + k][()], want, rt, at)
    compare(f"{tag}_timeseries_overlaps", r["timeseries/overlaps"][()], overlaps_so_far[frames])
    for k, want in veh.items():
        rt, at = tol_veh.get(k, (0, 0))
        if k in ("speed_var", "accel_var"):
            at = 1e-12 * ((Vw if k == "speed_var" else Aw) ** 2).mean(axis=0)
        compare(f"{tag}_vehicles_{k}", r["vehicles/" + k][()], want, rt, at)
    for k, want in summ.items():
        rt, at = tol_sum.get(k, (0, 0))
        if k == "throughput":
            rt = SUM
        compare(f"{tag}_summary_{k}", r["summary/" + k][()], want, rt, at)


check(traj_path, "ring_traj")
for i, p in enumerate(others):
    check(p, f"ring_fused{i}" if len(others) > 1 else "ring_fused")
sys.exit(1 if common.failures else 0)
