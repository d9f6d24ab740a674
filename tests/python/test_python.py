#!/usr/bin/python3
"""The Python package against bin/wavefuel (tests/t_python.sh runs it from the repository with PYTHONPATH=python).
Each check prints PASS name or FAIL name: why.

- energy: fuel and power at 10^6 random points split evenly over the shipped classes (infeasible accelerations, grades),
  with and without projection, equal `wavefuel energy`'s CSV bit for bit (%.17g read back is the exact double);
  flags equal; a_max equals the CIRCLES formula of energy.h computed here from the class's parameters;
- runs: a ring and a corridor run by Simulation.run give every dataset of `wavefuel run`'s result bit for bit
  (tests/fingerprint/fingerprint.py's digests; /meta wall times, start time, git hash and version excepted), run
  whole and in pieces of 1, 7 and 1000 steps; the summary equals /summary;
- state views: the ring's arrays are the engine's memory (no copy) and change in place as the run steps; the
  corridor's vehicles are in road order (positions decreasing from the front);
- two simulations at once, stepped alternately on different thread counts, each equal its own CLI result;
- errors: a bad key, a missing class, a bad value in a dict, a step after the end, an existing result: each a
  WavefuelError carrying wavefuel's message (file and key), the process alive."""
import gc
import os
import subprocess
import sys
import tempfile
import weakref

import numpy as np

sys.path.insert(0, "tests/fingerprint")
import fingerprint  # noqa: E402
import wavefuel  # noqa: E402

BIN = os.environ.get("WAVEFUEL_BIN", "bin/wavefuel")
fails = 0


def report(name, ok, why=""):
    global fails
    print(f"PASS {name}" if ok else f"FAIL {name}: {why}")
    fails += not ok


def cli(*args):
    return subprocess.run([BIN, *args], capture_output=True, text=True, check=True).stdout


# ------------------------------------------------------------------------------------------------ energy
def test_energy(tmp):
    """10^6 random points in all (issue 17), split evenly over the shipped classes, each with and without projection."""
    rng = np.random.default_rng(17)
    names = wavefuel.energy.class_names()
    n = -(-1_000_000 // len(names))
    for cls in names:
        v = rng.uniform(0, 40, n)  # `wavefuel energy` refuses speeds below 0 (docs/energy.md)
        a = rng.uniform(-4, 4, n)
        th = rng.uniform(-0.08, 0.08, n)
        pts = os.path.join(tmp, "pts.csv")
        np.savetxt(pts, np.column_stack((v, a, th)), fmt="%.17g", delimiter=",", header="v,a,theta", comments="")
        # Both CLI runs at once (the machine's two cores), read one after the other.
        runs = [subprocess.Popen([BIN, "energy", "--class", cls] + (["--project"] if p else []) + [pts],
                                 stdout=subprocess.PIPE, text=True) for p in (False, True)]
        outs = [r.communicate()[0] for r in runs]
        for project, out, run in zip((False, True), outs, runs):
            ref = np.loadtxt(out.splitlines()[1:], delimiter=",") if run.returncode == 0 else np.zeros((n, 6))
            vc = wavefuel.VehicleClass(cls)
            fuel, power, flag = vc.evaluate(v, a, th, project=project)
            same = (run.returncode == 0 and np.array_equal(ref[:, 0], v) and np.array_equal(ref[:, 3].view(np.uint64), fuel.view(np.uint64))
                    and np.array_equal(ref[:, 4].view(np.uint64), power.view(np.uint64))
                    and np.array_equal(ref[:, 5].astype(np.uint8), flag))
            k = np.flatnonzero(ref[:, 3] != fuel)[:1]
            report(f"python_energy_bits_{cls}{'_project' if project else ''}", same,
                   f"first difference at row {k}: CLI {ref[k, 3]} Python {fuel[k]}")
            same_fn = np.array_equal(wavefuel.energy.fuel(cls, v, a, th, project=project), fuel)
            report(f"python_energy_fuel_function_{cls}{'_project' if project else ''}", same_fn)
    print(f"  {n * len(names)} random points, {n} a class, each with and without projection")
    # a_max of a light-duty CIRCLES class: min(b1, b2 / max(v, 1e-12) - b3 v^2) - min(b4, b5 + b6 v) theta
    vc = wavefuel.VehicleClass("midsize_sedan")
    p = {k: val for k, (val, _) in vc.params.items()}
    vv, tt = v[:1000], th[:1000]
    ref = (np.minimum(p["b1"], p["b2"] / np.maximum(vv, 1e-12) - p["b3"] * vv * vv)
           - np.minimum(p["b4"], p["b5"] + p["b6"] * vv) * tt)
    got = wavefuel.energy.a_max("midsize_sedan", vv, tt)
    report("python_energy_a_max", np.allclose(got, ref, rtol=1e-14, atol=1e-14),
           f"largest difference {np.max(np.abs(got - ref))}")
    names = wavefuel.energy.class_names()
    listed = [line.split()[0] for line in cli("energy", "--list").splitlines()[1:]]
    report("python_energy_class_list", names == listed, f"{names} vs {listed}")
    report("python_energy_units", vc.params["b1"][1] == "m/s^2" and vc.keys["mass_kg"][1] == "kg",
           f"{vc.params['b1']} {vc.keys['mass_kg']}")


# -------------------------------------------------------------------------------------------------- runs
CASES = [  # name, scenario, overrides, threads
    ("ring", "scenarios/sugiyama.yaml", {"time.duration_s": 120, "time.warmup_s": 20}, 2),
    ("ring_av", "scenarios/ring_waves_av.yaml", {"time.duration_s": 60, "time.warmup_s": 10}, 1),
    ("corridor", "tests/data/tiny_corridor.yaml", {}, 2),
    ("corridor_bottleneck", "scenarios/corridor_bottleneck.yaml", {"time.duration_s": 400, "time.warmup_s": 60}, 2),
]


def cli_run(tmp, name, scenario, overrides, threads):
    out = os.path.join(tmp, f"{name}_cli.h5")
    sets = [x for k, val in overrides.items() for x in ("--set", f"{k}={val}")]
    cli("run", scenario, "-o", out, "--threads", str(threads), "-q", "--force", *sets)
    return out


def digests(path):
    return fingerprint.fingerprint_file(path)


def compare(name, ref, got):
    a, b = digests(ref), digests(got)
    diff = [x for x in set(a) ^ set(b)]
    report(name, a == b, f"{len(diff)} differing lines, e.g. {sorted(diff)[:4]}")


def test_runs(tmp):
    for name, scenario, overrides, threads in CASES:
        ref = cli_run(tmp, name, scenario, overrides, threads)
        out = os.path.join(tmp, f"{name}_py.h5")
        sim = wavefuel.Simulation(wavefuel.Scenario.load(scenario, overrides), threads=threads)
        summary = sim.run(output=out)
        compare(f"python_run_{name}", ref, out)
        res = wavefuel.read(out)
        fleet = {k: q for k, q in summary.items() if k != "classes"}
        ok = all(np.array_equal(res["summary/" + k], q.value, equal_nan=True)
                 and res.units["/summary/" + k] == q.units for k, q in fleet.items())
        ok = ok and all(np.array_equal(res["summary/" + k][c], q.value, equal_nan=True)
                        for c, cls in enumerate(sim.scenario.classes)
                        for k, q in summary["classes"][cls].items() if "summary/" + k in res)
        report(f"python_summary_{name}", ok and len(fleet) > 5, f"{len(fleet)} fields")
        sim.close()
        # The same run in pieces: 1, 7, 1000 steps and the rest.
        out = os.path.join(tmp, f"{name}_pieces.h5")
        sim = wavefuel.Simulation(wavefuel.Scenario.load(scenario, overrides), threads=threads, output=out)
        pieces = [1, 7, 1000, 1, 7]
        while not sim.done:
            sim.step(pieces[0])
            pieces = pieces[1:] + pieces[:1]
        report(f"python_run_{name}_time_at_end", sim.t == sim.scenario.n_steps * sim.scenario.dt_s,
               f"t = {sim.t}")
        compare(f"python_pieces_{name}", ref, out)
        sim.close()


def test_views():
    sim = wavefuel.Simulation(wavefuel.Scenario.load("scenarios/sugiyama.yaml"), threads=2)
    st = sim.state()
    x = st["x_m"]
    x0 = x.copy()
    addr = x.ctypes.data
    sim.step(5)
    st2 = sim.state()
    report("python_view_in_place", not np.array_equal(x, x0) and np.array_equal(x, st2["x_m"])
           and st2["x_m"].ctypes.data == addr and not x.flags.owndata,
           "x_m did not change in place")
    f = wavefuel._lib.lib.wf_sim_fleet(sim._ptr).contents
    import ctypes
    report("python_view_is_engine_memory", addr == ctypes.cast(f.x_m, ctypes.c_void_p).value
           and st["class_id"].dtype == np.uint16 and st["v_mps"].size == 22)
    try:
        x[0] = 0.0
        report("python_view_read_only", False, "a state view accepted a write")
    except ValueError:
        report("python_view_read_only", True)
    # A view keeps the engine alive after the Simulation is gone (no use after free); the last one frees it.
    run = weakref.ref(sim._run)
    del sim, st, st2, f
    gc.collect()
    alive = run() is not None and np.isfinite(x).all()
    del x
    gc.collect()
    report("python_view_keeps_run_alive", alive and run() is None, f"alive with a view: {alive}")
    sim = wavefuel.Simulation(wavefuel.Scenario.load("tests/data/tiny_corridor.yaml"), threads=2)
    sim.step(1200)
    st = sim.state()
    xs = st["x_m"]
    ok = xs.size == sim.n_vehicles > 5 and np.all(np.diff(xs) < 0) and np.all(np.diff(st["serial"].astype(float)) > 0)
    report("python_corridor_road_order", ok, f"{xs[:5]} serials {st['serial'][:5]}")
    sim.close()
    # A short corridor whose circular buffer wraps: at every step the vehicles are in road order (front first,
    # serials increasing towards the back) whether state() gives views (contiguous slots) or copies (wrapped).
    short = {"road.length_m": 300, "road.zones[0].from_m": 150, "road.zones[0].to_m": 200,
             "corridor.detectors.x_m[0]": 100, "corridor.detectors.x_m[1]": 250}
    sim = wavefuel.Simulation(wavefuel.Scenario.load("tests/data/tiny_corridor.yaml", short), threads=1)
    vh = wavefuel._lib.lib.wf_corridor_vehicles(wavefuel._lib.lib.wf_sim_corridor(sim._ptr)).contents
    seen = {True: 0, False: 0}
    ok = True
    while not sim.done and ok:
        sim.step(1)
        st = sim.state()
        n = st["x_m"].size
        if n < 2:
            continue
        view = not st["x_m"].flags.owndata
        seen[view] += 1
        ok = (view == (vh.first + vh.n <= vh.cap) and np.all(np.diff(st["x_m"]) < 0)
              and np.all(np.diff(st["serial"].astype(np.int64)) > 0))
    report("python_corridor_wrapped_buffer", ok and seen[True] > 0 and seen[False] > 0,
           f"at t = {sim.t}: {seen[True]} view steps, {seen[False]} copy steps")
    sim.close()


def test_views_vs_file(tmp):
    """The ring's views against what the writer saw: x and v at each trajectory frame's instant; acceleration and
    fuel rate of the step that starts there (the per-step arrays hold the last step's values, taken at its start);
    fuel, final position and speed, class and group per vehicle at the end (/vehicles)."""
    out = os.path.join(tmp, "views.h5")
    short = {"time.duration_s": 100, "time.warmup_s": 20}
    sim = wavefuel.Simulation(wavefuel.Scenario.load("scenarios/sugiyama.yaml", short), threads=2, output=out)
    st = sim.state()
    at, after = {}, {}
    while not sim.done:
        at[sim.steps_done] = (st["x_m"].copy(), st["v_mps"].copy())
        sim.step(1)
        after[sim.steps_done - 1] = (st["a_mps2"].copy(), st["fuel_rate_gps"].copy())
        if not sim.done:  # the call after the last step takes the final record and ends the run
            sim.step(24)
    res = wavefuel.read(out)
    n, bad = 0, []
    for i, t in enumerate(res["trajectories/t"]):
        k = int(round(float(t) / sim.scenario.dt_s))
        if k in at and k in after:
            n += 1
            got = at[k] + after[k]
            ref = [res[f"trajectories/{c}"][i] for c in ("x", "v", "a", "fuel_rate")]
            bad += [f"{c} at t = {t}" for c, g, r in zip(("x", "v", "a", "fuel_rate"), got, ref)
                    if not np.array_equal(g, r)]
    end = [(c, st[k], res[f"vehicles/{c}"]) for c, k in (("fuel", "fuel_g"), ("final_x", "x_m"), ("final_v", "v_mps"),
                                                          ("class_id", "class_id"), ("group_id", "group_id"))]
    bad += [c for c, g, r in end if not np.array_equal(g, r)]
    report("python_views_match_result", n >= 40 and not bad, f"{n} frames compared; differ: {bad[:6]}")
    sim.close()


def test_corridor_views_vs_file(tmp):
    """The corridor's vehicles in road order against the trajectory frames the writer recorded at the same instant:
    the same serials in the same order with the same positions and speeds; a frame may also hold the vehicles that
    enter at that instant (inserted at the start of the next step), never others."""
    out = os.path.join(tmp, "corridor_views.h5")
    sim = wavefuel.Simulation(wavefuel.Scenario.load("tests/data/tiny_corridor.yaml"), threads=2, output=out)
    snaps = {}
    while not sim.done:
        st = sim.state()
        snaps[sim.steps_done] = (st["serial"].copy(), st["x_m"].copy(), st["v_mps"].copy())
        sim.step(5)
    res = wavefuel.read(out)
    t, n, bad = res["trajectories/t"], 0, []
    for k, (serial, x, v) in snaps.items():
        rows = np.flatnonzero(np.abs(t - k * sim.scenario.dt_s) < 1e-9)
        if rows.size == 0:
            continue
        n += 1
        fs = res["trajectories/serial"][rows].astype(np.int64)
        known = np.isin(fs, serial.astype(np.int64))
        same = (np.array_equal(fs[known], serial) and np.array_equal(res["trajectories/x"][rows][known], x)
                and np.array_equal(res["trajectories/v"][rows][known], v)
                and (serial.size == 0 or np.all(fs[~known] > serial.max())))
        if not same:
            bad.append(k)
    report("python_corridor_views_match_result", n > 100 and not bad, f"{n} frames; differ at steps {bad[:5]}")
    sim.close()


def test_two_sims(tmp):
    name_a, scen_a, over_a, thr_a = CASES[0]
    name_b, scen_b, over_b, thr_b = CASES[2]
    ref_a = os.path.join(tmp, f"{name_a}_cli.h5")
    ref_b = os.path.join(tmp, f"{name_b}_cli.h5")
    out_a, out_b = os.path.join(tmp, "two_a.h5"), os.path.join(tmp, "two_b.h5")
    a = wavefuel.Simulation(wavefuel.Scenario.load(scen_a, over_a), threads=thr_a, output=out_a)
    b = wavefuel.Simulation(wavefuel.Scenario.load(scen_b, over_b), threads=1, output=out_b)
    while not (a.done and b.done):
        if not a.done:
            a.step(37)
        if not b.done:
            b.step(101)
    a.close()
    b.close()
    compare("python_two_sims_ring", ref_a, out_a)
    # b ran on 1 thread, its CLI reference on 2: the same bits for any thread count; /meta/threads differs
    da = [x for x in digests(ref_b) if not x.startswith("/meta/threads ")]
    db = [x for x in digests(out_b) if not x.startswith("/meta/threads ")]
    report("python_two_sims_corridor", da == db, f"{sorted(set(da) ^ set(db))[:4]}")


def expect_error(name, fn, *needles):
    try:
        fn()
    except wavefuel.WavefuelError as e:
        msg = str(e)
        report(name, all(s in msg for s in needles), f"message {msg!r} lacks one of {needles}")
        return
    except Exception as e:  # noqa: BLE001
        report(name, False, f"{type(e).__name__}: {e}")
        return
    report(name, False, "no exception")


def test_errors(tmp):
    expect_error("python_error_bad_override", lambda: wavefuel.Scenario.load("scenarios/sugiyama.yaml",
                                                                              {"time.durationn_s": 5}),
                 "time.durationn_s", "duration_s")
    tiny = {"name": "tiny", "road": {"length_m": 400}, "time": {"duration_s": 20, "dt_s": 0.1},
            "fleet": {"vehicles": 16, "classes": [{"class": "midsize_sedan", "fraction": 1.0}],
                      "drivers": [{"model": "idm", "fraction": 1.0, "noise_mps2": 0.3}]}}
    bad = dict(tiny, time={"duration_s": 20, "dt_ss": 0.1})
    expect_error("python_error_bad_key", lambda: wavefuel.Scenario.from_dict(bad, path=os.path.join(tmp, "b.yaml")),
                 "b.yaml", "dt_ss")
    missing = dict(tiny, fleet={"vehicles": 10, "classes": [{"class": "no_such_class", "fraction": 1}]})
    expect_error("python_error_missing_class",
                 lambda: wavefuel.Scenario.from_dict(missing, path=os.path.join(tmp, "d.yaml")),
                 "no_such_class", "d.yaml")
    expect_error("python_error_bad_value",
                 lambda: wavefuel.Scenario.load("scenarios/sugiyama.yaml", ["time.dt_s=-1"]), "dt_s", "-1")
    expect_error("python_error_missing_file", lambda: wavefuel.Scenario.load(os.path.join(tmp, "none.yaml")),
                 "none.yaml")
    expect_error("python_error_energy_class", lambda: wavefuel.energy.fuel("no_such_class", 1.0, 0.0),
                 "no_such_class")
    sim = wavefuel.Simulation(wavefuel.Scenario.load("tests/data/tiny_ring.yaml",
                                                        {"time.duration_s": 2, "time.warmup_s": 0}))
    sim.run()
    expect_error("python_error_step_after_end", lambda: sim.step(), "ended")
    existing = os.path.join(tmp, "ring_cli.h5")
    sim2 = wavefuel.Simulation(wavefuel.Scenario.load("tests/data/tiny_ring.yaml"))
    expect_error("python_error_existing_result", lambda: sim2.run(output=existing), "ring_cli.h5")
    sim2.close()
    expect_error("python_error_closed", lambda: sim2.step(), "closed")
    ring = "tests/data/tiny_ring.yaml"
    expect_error("python_error_steps", lambda: wavefuel.Simulation(ring).step(0), "at least 1")
    expect_error("python_error_threads", lambda: wavefuel.Simulation(ring, threads=0), "threads")
    # a dict scenario equals its file: the same text as JSON
    d = tiny
    path = os.path.join(tmp, "tiny.yaml")
    with open(path, "w") as f:
        f.write("name: tiny\nroad: {length_m: 400}\ntime: {duration_s: 20, dt_s: 0.1}\n"
                "fleet:\n  vehicles: 16\n  classes: [{class: midsize_sedan, fraction: 1.0}]\n"
                "  drivers: [{model: idm, fraction: 1.0, noise_mps2: 0.3}]\n")
    s1 = wavefuel.Simulation(wavefuel.Scenario.from_dict(d, path=path)).run()
    s2 = wavefuel.Simulation(wavefuel.Scenario.load(path)).run()
    report("python_from_dict", s1 == s2 and s1["fuel"].value > 0, f"{s1['fuel']} vs {s2['fuel']}")


def main():
    with tempfile.TemporaryDirectory() as tmp:
        test_energy(tmp)
        test_runs(tmp)
        test_views()
        test_views_vs_file(tmp)
        test_corridor_views_vs_file(tmp)
        test_two_sims(tmp)
        test_errors(tmp)
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())
