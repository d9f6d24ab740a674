"""Shared pieces of the independent recomputations (tests/recompute/ring.py, corridor.py): comparisons that print
one "PASS name" / "FAIL name: ..." line each, the event counters of docs/metrics.md written as plain loops over a
vehicle's step samples, and the energy model evaluated through `wavefuel energy` (the class model as a user calls
it, not the engine's vectorised path)."""
import subprocess
import sys

import h5py
import numpy as np
import yaml  # python3-yaml (Debian): the scenario text a result stores is plain YAML

failures = 0


def open_run(argv):
    """The command line BIN TRAJ.h5 [OTHER.h5 ...] TMPDIR, and the run's settings: the statistics thresholds from
    the scenario text stored in /meta (with the defaults of docs/scenarios.md), dt, warm-up and road length."""
    bin_path, traj_path, others, tmp = argv[1], argv[2], argv[3:-1], argv[-1]
    f = h5py.File(traj_path)
    st = yaml.safe_load(f["meta/scenario_text"][()].decode()).get("statistics", {})
    v_go = st.get("v_go_mps", 2.0)
    thresholds = (st.get("v_stop_mps", 0.5), v_go, st.get("hard_brake_mps2", 1.0), st.get("wave_speed_mps", v_go))
    return bin_path, f, others, tmp, thresholds, f["meta/dt"][()], f["meta/warmup"][()], f["meta/road_length"][()]


def report(name, bad, detail=""):
    global failures
    if bad:
        failures += 1
        print(f"FAIL {name}: {detail}")
    else:
        print(f"PASS {name}")


def compare(name, got, want, rtol=0.0, atol=0.0):
    """got and want element-wise within atol + rtol * |want| (0, 0: bit for bit); NaN matches NaN."""
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    if got.shape != want.shape:
        report(name, True, f"shape {got.shape}, want {want.shape}")
        return
    same = (np.isnan(got) & np.isnan(want)) | (got == want)   # NaN matches NaN, inf matches inf
    with np.errstate(invalid="ignore"):
        err = np.where(same, 0.0, np.abs(got - want))
    lim = atol + rtol * np.abs(want)
    bad = ~same & ~(err <= lim)
    if bad.any():
        i = np.unravel_index(np.argmax(np.where(bad, err - lim, -np.inf)), got.shape)
        lim_i = np.broadcast_to(lim, got.shape)[i]
        report(name, True, f"{int(bad.sum())} of {got.size} values off; worst at {tuple(int(j) for j in i)}: got "
                           f"{got[i]!r}, want {want[i]!r} (allowed {lim_i:.3g})")
    else:
        report(name, False)


def stops(v, start_moving, counted, v_stop, v_go):
    """Stops of one vehicle: v[k] speed at the start of step k (k = 0..K, v[K] after the last step); a stop begins
    when the speed after a step falls below v_stop while the vehicle is moving; it moves again once above v_go.
    counted[k]: step k is in the window."""
    n, moving = 0, start_moving
    for k in range(len(v) - 1):
        if moving and v[k + 1] < v_stop:
            moving = False
            n += counted[k]
        elif not moving and v[k + 1] > v_go:
            moving = True
    return n


def stops_all(v, counted, v_stop, v_go):
    """stops() for every column of v [step x vehicle], vectorised over vehicles; a vehicle starting faster than v_go
    counts as moving."""
    moving = v[0] > v_go
    n = np.zeros(v.shape[1], dtype=np.int64)
    for k in range(v.shape[0] - 1):
        vn = v[k + 1]
        stop = moving & (vn < v_stop)
        n += stop & bool(counted[k])
        moving = (moving & ~stop) | (~moving & (vn > v_go))
    return n


def hard_brake_onsets(a, counted, hard, braking_before=None):
    """Steps where a < -hard while the previous step's a was not (a [step x vehicle]); braking_before: whether the
    step before the first was braking (default: not)."""
    br = a < -hard
    prev = np.zeros_like(br[:1]) if braking_before is None else braking_before[None, :]
    onset = br & ~np.concatenate([prev, br[:-1]], axis=0)
    return (onset & counted[:, None]).sum(axis=0)


def energy(bin_path, cls, v, a, theta, workdir):
    """(fuel rate g/s, flag) of class `cls` at the rows (v, a, theta), through `wavefuel energy` (CSV in and out,
    17 significant digits: every double round-trips)."""
    src = f"{workdir}/energy_in_{cls}.csv"
    np.savetxt(src, np.column_stack([v, a, theta]), fmt="%.17g", delimiter=",")
    out = subprocess.run([bin_path, "energy", "--class", cls, src], capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"wavefuel energy --class {cls} failed: {out.stderr}")
    rows = np.loadtxt(out.stdout.splitlines()[1:], delimiter=",", ndmin=2)
    return rows[:, 3], rows[:, 5].astype(int)


def waves(slow, circular):
    """Maximal runs of consecutive True in `slow` (ring order: vehicle i's follower is i - 1; road order for a
    corridor: front first). Circular: a run may wrap from the last vehicle to the first, and an all-slow ring is one
    wave."""
    slow = np.asarray(slow, dtype=bool)
    if slow.size == 0:
        return 0
    if circular:
        starts = int((slow & ~np.roll(slow, 1)).sum())
        return 1 if starts == 0 and slow.all() else starts
    return int(slow[0]) + int((slow[1:] & ~slow[:-1]).sum())
