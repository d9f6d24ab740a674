"""External controllers and RL environments from Python (docs/python.md, docs/controllers.md): prints PASS/FAIL lines.

- An external group driven from Python with the IDM formula (written here in numpy, from Treiber et al.'s equation,
  not through the library) gives the bits of the same group with `model: idm`: every dataset of the result files
  (those naming the model or its parameters aside) and the final state.
- RingEnv and TrajectoryEnv follow the Gymnasium API: shapes and spaces, determinism for a seed, the ring length
  drawn per episode, truncation at the horizon; each term of the reward (fuel of the vehicles in scope, gap bounds,
  comfort) recomputed here from the states before and after the action (positions, speeds, groups) with numpy and
  the class's energy model, and their sum.
- VectorEnv: the bits of the same environments stepped one by one (observations, rewards and their terms,
  truncations, autoresets), on 1 and 2 threads, rings of different lengths and trajectories of different traces; an
  environment's observations equal a plain Simulation's driven by set_actions / step / observe.
- VectorEnv's small rings stepped side by side in shared blocks of the kernel: the bits of the rings alone, across a
  record step and overlap repairs.
- The library's batch calls (wf_sims_set_actions, wf_sims_step, wf_sims_observe) equal the runs stepped alone.
- Refusals: commands to a group that is not external, the wrong count, an infinite command, an unknown group."""
import os
import re
import sys
import tempfile

import h5py
import numpy as np

import wavefuel as wf

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
failures = 0


def check(name, ok, detail=""):
    global failures
    print(("PASS " if ok else "FAIL ") + name + ("" if ok else ": " + str(detail)))
    sys.stdout.flush()
    failures += not ok


RING = {
    "name": "ext_ring", "seed": 11, "road": {"length_m": 600},
    "time": {"duration_s": 120, "dt_s": 0.1, "output_interval_s": 1.0, "warmup_s": 10},
    "fleet": {"vehicles": 30, "placement": "interleaved", "classes": [{"class": "midsize_sedan", "fraction": 1.0}],
              "drivers": [{"name": "human", "model": "idm", "fraction": 0.8, "noise_mps2": 0.3},
                          {"name": "av", "model": "idm", "fraction": 0.2, "noise_mps2": 0.3}]},
    "initial": {"state": "rest", "jitter_m": 0.5},
    "output": {"trajectories": True, "trajectory_interval_s": 1.0},
}


def idm(obs, v0=30.0, T=1.0, s0=2.0, a=1.0, b=1.5):
    """IDM with the defaults of docs/models.md, in the order of operations of the paper's formula."""
    v, vl, gap = obs[:, 0], obs[:, 1], obs[:, 2]
    x = v / v0
    x2 = x * x
    dyn = v * T + v * (v - vl) / (2.0 * np.sqrt(a * b))
    s_star = s0 + np.where(dyn > 0.0, dyn, 0.0)
    s = np.where(gap > 1e-3, gap, 1e-3)
    r = s_star / s
    return a * (1.0 - x2 * x2 - r * r)


def datasets(path):
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            skip = name.startswith("meta/") or name.startswith("drivers/model") or "/param_" in name
            if isinstance(obj, h5py.Dataset) and not skip:
                out[name] = obj[()]
        f.visititems(visit)
    return out


def test_idm_from_python(tmp):
    ref = os.path.join(tmp, "idm.h5")
    with wf.Simulation(wf.Scenario.from_dict(RING), threads=2, output=ref) as sim:
        sim.run()
        x_ref, v_ref = np.array(sim.state()["x_m"]), np.array(sim.state()["v_mps"])
    d = dict(RING, fleet=dict(RING["fleet"]))
    d["fleet"]["drivers"] = [RING["fleet"]["drivers"][0], dict(RING["fleet"]["drivers"][1], model="external")]
    out = os.path.join(tmp, "ext.h5")
    commands = 0
    with wf.Simulation(wf.Scenario.from_dict(d), threads=2, output=out) as sim:
        while not sim.done:
            obs = sim.observe("av")
            sim.set_actions("av", idm(obs))
            commands += len(obs)
            sim.step(1)
        x, v = np.array(sim.state()["x_m"]), np.array(sim.state()["v_mps"])
    a, b = datasets(ref), datasets(out)
    def raw(x):
        x = np.asarray(x)
        return (x.dtype.str, x.shape, x.tobytes()) if x.dtype.kind in "fiub" else (x.shape, x.tolist())
    differ = [n for n in a if n not in b or raw(a[n]) != raw(b[n])]
    check("idm_from_python_equals_model_idm", not differ and set(a) == set(b) and x.tobytes() == x_ref.tobytes()
          and v.tobytes() == v_ref.tobytes() and commands == 6 * 1201,
          f"{len(differ)} datasets differ ({differ[:4]}), {commands} commands")
    print(f"  {len(a)} datasets and the final state bit-identical; {commands} commands from Python")


def test_refusals():
    with wf.Simulation(wf.Scenario.from_dict(dict(RING, fleet=dict(RING["fleet"], drivers=[
            RING["fleet"]["drivers"][0], dict(RING["fleet"]["drivers"][1], model="external")])))) as sim:
        def raises(fn, text):
            try:
                fn()
            except wf.WavefuelError as e:
                return text in str(e)
            return False
        check("set_actions_refuses_human_group", raises(lambda: sim.set_actions("human", np.zeros(24)),
                                                       "takes no commands"))
        check("set_actions_refuses_count", raises(lambda: sim.set_actions("av", np.zeros(5)), "6 vehicles"))
        check("set_actions_refuses_inf", raises(lambda: sim.set_actions("av", [0, 0, np.inf, 0, 0, 0]),
                                                "command 2 is inf"))
        check("observe_refuses_unknown_group", raises(lambda: sim.observe("robots"), "no driver group 'robots'"))
        check("group_size", sim.group_size("av") == 6 and sim.group_size(0) == 24)


def run_episode(env, seed, actions):
    obs, info = env.reset(seed=seed)
    trace = [obs.copy()]
    rewards, steps = [], 0
    while True:
        obs, r, term, trunc, info = env.step(actions(obs))
        trace.append(obs.copy())
        rewards.append(r)
        steps += 1
        if term or trunc:
            break
    return np.array(trace), np.array(rewards), steps, info


def test_ring_env():
    env = wf.envs.RingEnv(n_av=2, horizon_s=20.0, warmup_s=5.0)
    try:
        env.step(np.zeros(2))
        early = "no error"
    except RuntimeError as e:
        early = str(e)
    check("ring_env_step_before_reset", "before reset" in early, early)
    obs, info = env.reset(seed=4)
    check("ring_env_reset", obs.shape == (2, 3) and env.observation_space.shape == (2, 3)
          and env.action_space.shape == (2,) and abs(info["t"] - 5.0) < 1e-9, (obs.shape, info))
    zero = lambda o: np.zeros(2)
    t1, r1, n1, i1 = run_episode(env, 7, zero)
    t2, r2, n2, _ = run_episode(env, 7, zero)
    check("ring_env_deterministic", t1.tobytes() == t2.tobytes() and r1.tobytes() == r2.tobytes())
    check("ring_env_truncates_at_horizon", n1 == 200 and abs(i1["t"] - 25.0) < 1e-9, (n1, i1))
    check("ring_env_reward_is_fuel", np.all(r1 < 0) and np.all(np.isfinite(r1)))
    lengths = set()
    for s in range(4):
        env.reset(seed=s)
        lengths.add(round(float(env.scenario_dict["road"]["length_m"]), 6))
    check("ring_env_length_drawn", len(lengths) == 4 and all(220 <= L <= 270 for L in lengths), lengths)
    env.close()


def test_actions_clipped():
    """Actions outside the action space (beyond its bounds, infinite, exactly on them, NaN for none) are clipped in
    C (RlBatch's bounds) as numpy's minimum(maximum(u, low), high): a RingEnv given them, and its twin without bounds
    (an action space without bounds) given numpy's clipped values, step the same bits, alone and in a VectorEnv."""
    kw = dict(n_av=3, horizon_s=30.0, warmup_s=2.0, accel_range_mps2=(-1.0, 0.5))
    rng = np.random.default_rng(3)
    acts = rng.uniform(-4.0, 4.0, (250, 3))
    acts[::7, 0], acts[::11, 1], acts[::13, 2] = np.inf, -np.inf, 0.5
    acts[::17, 0], acts[5::19, 2] = -1.0, np.nan
    clipped = np.minimum(np.maximum(acts, -1.0), 0.5)
    env, twin = wf.envs.RingEnv(**kw), wf.envs.RingEnv(**dict(kw, accel_range_mps2=(-np.inf, np.inf)))
    env.reset(seed=8), twin.reset(seed=8)
    same = all(a[0].tobytes() == b[0].tobytes() and a[1] == b[1]
               for a, b in ((env.step(u), twin.step(c)) for u, c in zip(acts, clipped)))
    venv = wf.envs.VectorEnv(2, threads=2, thread_check=0, **kw)
    venv.reset(seed=8)
    both = np.stack([acts, acts[::-1]], axis=1)
    out = [venv.step(u)[0][0].copy() for u in both]
    twin.reset(seed=8)
    same_vec = all(o.tobytes() == twin.step(c)[0].tobytes() for o, c in zip(out, clipped))
    check("actions_clipped_as_numpy", same and same_vec and np.isnan(acts).any(), (same, same_vec))
    for e in (env, twin, venv):
        e.close()


def reward_by_hand(rw, st0, st1, av, dt, length_m, ring, a_prev, cls="midsize_sedan"):
    """The reward's terms recomputed from two states (sim.state() at an action's start and end) with numpy and the
    class's energy model: fuel of the vehicles in scope, the automated vehicles' gaps from their positions, their
    accelerations and jerks from their speeds (docs/python.md)."""
    v0, v1, x1 = (np.array(st[k], np.float64) for st, k in ((st0, "v_mps"), (st1, "v_mps"), (st1, "x_m")))
    group = np.array(st1["group_id"])
    car = wf.VehicleClass(cls).keys["length_m"][0]
    if ring:  # ring order, vehicle i + 1 leads i; the last one's leader is vehicle 0 a lap ahead
        lead_x = np.append(x1[1:], x1[0] + length_m)
        scope = np.ones(v0.size, bool)
    else:  # front first: each vehicle's leader is the previous one; the front one's is the virtual leader
        lead_x = np.append(np.nan, x1[:-1])
        scope = np.arange(v0.size) >= np.flatnonzero(group == av)[0]
        if rw.fuel_scope == "all":
            scope[:] = True
    fuel = np.mean(wf.energy.fuel(cls, v0, (v1 - v0) / dt, 0.0)[scope])
    gap = (lead_x - car - x1)[group == av]
    lo, hi = rw.gap_range_m
    viol = np.where(gap < lo, (lo - gap) ** 2, np.where(gap > hi, (gap - hi) ** 2, 0.0))
    a = ((v1 - v0) / dt)[group == av]
    jerk = np.zeros_like(a) if a_prev is None else (a - a_prev) / dt
    terms = {"fuel": -rw.w_fuel * fuel, "gap": -rw.w_gap * np.mean(viol),
             "comfort": -rw.w_accel * np.mean(a * a) - rw.w_jerk * np.mean(jerk * jerk)}
    return terms, a


def close(a, b, tol=1e-12):
    return abs(a - b) <= tol * max(abs(a), abs(b), 1e-300)


def test_reward_terms():
    """Each term of the reward and their sum against reward_by_hand, over three actions (the jerk from the second),
    on a ring with gap bounds that bind and on a corridor platoon."""
    rw = wf.envs.Reward(gap_range_m=(8.0, 9.0), w_gap=0.5, w_accel=0.1, w_jerk=0.01)
    env = wf.envs.RingEnv(n_av=2, horizon_s=20.0, warmup_s=5.0, action_every=2, reward=rw)
    env.reset(seed=9)
    bad, a_prev, seen = [], None, {k: 0.0 for k in ("fuel", "gap", "comfort")}
    for u in ([0.5, -1.0], [1.5, 0.2], [-2.0, 0.0]):
        st0 = {k: np.array(x) for k, x in env.sim.state().items()}
        _, r, _, _, info = env.step(np.array(u))
        want, a_prev = reward_by_hand(rw, st0, env.sim.state(), 1, 0.2, env.scenario_dict["road"]["length_m"], True,
                                      a_prev)
        got = info["reward_terms"]
        bad += [(k, got[k], want[k]) for k in want if not close(got[k], want[k])]
        bad += [] if close(r, sum(got.values()), 1e-15) else [("sum", r, got)]
        seen = {k: min(seen[k], got[k]) for k in seen}
    check("reward_terms_ring", not bad and all(x < 0 for x in seen.values()), (bad, seen))
    env.close()
    t = np.arange(0.0, 30.1, 1.0)
    trace = (t, 20.0 + 5.0 * np.sin(2 * np.pi * t / 15.0))
    for scope in ("platoon", "all"):
        rw = wf.envs.Reward(fuel_scope=scope, gap_range_m=(30.0, 40.0))
        env = wf.envs.TrajectoryEnv(trace, n_vehicles=12, humans_per_av=2, reward=rw)
        env.reset(seed=3)
        bad, a_prev, gap = [], None, 0.0
        for u in ([0.3] * 4, [-0.5] * 4):
            st0 = {k: np.array(x) for k, x in env.sim.state().items()}
            _, r, _, _, info = env.step(np.array(u))
            want, a_prev = reward_by_hand(rw, st0, env.sim.state(), 1, 0.1, None, False, a_prev)
            got = info["reward_terms"]
            gap = min(gap, got["gap"])
            bad += [(k, got[k], want[k]) for k in want if not close(got[k], want[k])]
            bad += [] if close(r, sum(got.values()), 1e-15) else [("sum", r, got)]
        first_av = int(np.flatnonzero(np.array(env.sim.state()["group_id"]) == 1)[0])
        check(f"reward_terms_corridor_{scope}", not bad and gap < 0, (bad, gap))
        if scope == "platoon":
            print(f"  corridor platoon: the fuel of the {12 - first_av} vehicles from the first automated one back")
        env.close()
    env.close()


def test_trajectory_env(tmp):
    t = np.arange(0.0, 60.1, 1.0)
    v = 20.0 + 8.0 * np.sin(2 * np.pi * t / 30.0)
    csv = os.path.join(tmp, "trace.csv")
    np.savetxt(csv, np.column_stack([t, v]), delimiter=",", header="time_s,speed_mps", comments="")
    env = wf.envs.TrajectoryEnv(csv, n_vehicles=15, humans_per_av=4)
    obs, info = env.reset(seed=1)
    check("trajectory_env_reset", obs.shape == (3, 3) and env.sim.n_vehicles == 15, (obs.shape, env.sim.n_vehicles))
    # The leader replays the trace: the platoon's front vehicle follows it.
    tr, r, n, last = run_episode(env, 1, lambda o: np.zeros(3))
    check("trajectory_env_episode", n == 600 and np.all(np.isfinite(r)) and np.all(r < 0), (n, r[:3]))
    s = env.sim.state()
    check("trajectory_env_platoon_kept", s["x_m"].size == 15 and list(s["group_id"]).count(1) == 3)
    env.close()


def single_runs(make, seeds, actions):
    """Environments made by make(i), each stepped alone with actions[:, i] and reset (from its own generator) when
    its episode ends: what VectorEnv must reproduce. Returns per step (obs, rewards, truncated, terms, final obs)."""
    envs = [make(i) for i in range(len(seeds))]
    first = np.stack([e.reset(seed=s)[0] for e, s in zip(envs, seeds)])
    out = []
    for u in actions:
        rows = [e.step(u[i]) for i, e in enumerate(envs)]
        obs = np.stack([r[0] for r in rows])
        trunc = np.array([r[3] for r in rows])
        final = {i: obs[i].copy() for i in np.flatnonzero(trunc)}
        for i in final:
            obs[i] = envs[i].reset()[0]
        terms = {k: np.array([r[4]["reward_terms"][k] for r in rows]) for k in ("fuel", "gap", "comfort")}
        terms["t"] = np.array([r[4]["t"] for r in rows])
        out.append((obs, np.array([r[1] for r in rows]), trunc, terms, final))
    for e in envs:
        e.close()
    return first, out


def test_vector_env(tmp):
    """VectorEnv against the same environments stepped one by one (bits of observations, rewards, terms,
    truncations, autoresets), on 1 and 2 threads; and the first environment's observations against a plain
    Simulation of its episode's scenario driven by set_actions / step / observe."""
    # Different lengths, and horizons (15, 12 and 18 actions) so that episodes end at different steps.
    per_env = [{"length_range_m": (220.0 + 20 * i, 230.0 + 20 * i), "horizon_s": h} for i, h in
               enumerate((3.0, 2.4, 3.6))]
    kw = dict(n_av=2, warmup_s=2.0, action_every=2, reward=wf.envs.Reward(gap_range_m=(8.0, 9.0)))
    rng = np.random.default_rng(2)
    actions = rng.uniform(-2.0, 2.0, (40, 3, 2))
    first, ref = single_runs(lambda i: wf.envs.RingEnv(**kw, **per_env[i]), [10, 11, 12], actions)
    # The last case: the thread governor probing at every action (one thread, then two, ...): the same bits.
    for threads, thread_check in ((1, None), (2, None), (2, 1)):
        venv = wf.envs.VectorEnv(3, threads=threads, per_env=per_env, thread_check=thread_check, **kw)
        obs, info = venv.reset(seed=10)
        bad = [] if obs.tobytes() == first.tobytes() and obs.shape == (3, 2, 3) else ["reset"]
        resets = 0
        # Gymnasium's vector infos: every key K with its mask "_K", all True but for final_obs / final_info.
        masks = lambda d: {k: masks(x) if isinstance(x, dict) else x.tolist() for k, x in d.items()  # noqa: E731
                           if k.startswith("_") and k not in ("_final_obs", "_final_info") or isinstance(x, dict)}
        masks_want = {k: [True] * 3 for k in ("_t", "_fuel_rate_gps", "_mean_speed_mps", "_reward_terms")}
        masks_want["reward_terms"] = {k: [True] * 3 for k in ("_fuel", "_gap", "_comfort")}
        for k, u in enumerate(actions):
            obs, r, term, trunc, info = venv.step(u)
            o, rr, tt, terms, final = ref[k]
            same = (obs.tobytes() == o.tobytes() and r.tobytes() == rr.tobytes() and np.array_equal(trunc, tt)
                    and not term.any() and all(info["reward_terms"][t].tobytes() == terms[t].tobytes()
                                               for t in terms if t != "t")
                    and info["t"].tobytes() == terms["t"].tobytes() and masks(info) == masks_want
                    and all(info["final_obs"][i].tobytes() == final[i].tobytes() for i in final)
                    and (not final or list(np.flatnonzero(info["_final_obs"])) == sorted(final)
                         == list(np.flatnonzero(info["_final_info"])))
                    and all(info["final_info"][i]["t"] == terms["t"][i]
                            and info["final_info"][i]["reward_terms"]["fuel"] == terms["fuel"][i] for i in final))
            resets += len(final)
            if not same:
                bad.append(k)
        probes, switches = venv.thread_governor
        if thread_check is None:  # the library's default, as docs/python.md and the docstring quote it
            quoted = {re.search(r"None: (?:the library's default, )?(\d+)", text).group(1)
                      for text in (open(os.path.join(ROOT, "docs", "python.md")).read(), wf.envs.VectorEnv.__doc__)}
            check(f"vector_env_thread_check_default_quoted_{threads}", quoted == {str(venv._batch.thread_check())},
                  (quoted, venv._batch.thread_check()))
        name = f"vector_env_equals_single_envs_threads_{threads}" + ("_governor" if thread_check else "")
        # the rings side by side in every action (records come every 1000 steps; autoresets rebuild the batch)
        check(name, not bad and resets == 7 and (probes >= 5 if thread_check else not probes or threads > 1)
              and venv.side_by_side == len(actions), (bad[:5], resets, probes, venv.side_by_side))
        if threads == 2:
            print(f"  3 rings, {len(actions)} actions, {resets} autoresets: the bits of the environments alone"
                  + (f" ({probes} probes of the thread governor, {switches} switches)" if thread_check else ""))
        venv.close()
    # Environment 0's first episode in a plain Simulation: warm-up, then the same (clipped) commands.
    sim = wf.Simulation(wf.Scenario.from_dict(ref_scenario(kw, per_env[0], 10)), threads=1)
    sim.step(20)
    got = []
    for u in actions[:15, 0]:
        sim.set_actions("av", np.clip(u, -3.0, 3.0))
        sim.step(2)
        got.append(sim.observe("av"))
    want = [ref[k][0][0] if not ref[k][2][0] else None for k in range(15)]
    same = all(w is None or g.tobytes() == w.tobytes() for g, w in zip(got, want))
    check("vector_env_equals_plain_simulation", same and sum(w is not None for w in want) == 14)
    # Trajectory environments with different traces, on 2 threads, against the same alone.
    t = np.arange(0.0, 40.1, 1.0)
    traces = [{"trace": (t, 20.0 + a * np.sin(2 * np.pi * t / 20.0))} for a in (3.0, 6.0)]
    kw = dict(n_vehicles=10, humans_per_av=4)
    acts = rng.uniform(-1.0, 1.0, (30, 2, 2))
    first, ref = single_runs(lambda i: wf.envs.TrajectoryEnv(**kw, **traces[i]), [4, 5], acts)
    venv = wf.envs.VectorEnv(2, env=wf.envs.TrajectoryEnv, threads=2, per_env=traces, **kw)
    obs, _ = venv.reset(seed=4)
    same = obs.tobytes() == first.tobytes()
    for k, u in enumerate(acts):
        obs, r, _, _, info = venv.step(u)
        same &= obs.tobytes() == ref[k][0].tobytes() and r.tobytes() == ref[k][1].tobytes()
    check("vector_env_trajectory_equals_single_envs", same and venv.observation_space.shape == (2, 2, 3))
    venv.close()
    def refused(fn, text):
        try:
            fn()
        except ValueError as e:
            return text in str(e)
        return False
    check("vector_env_refuses_mixed_n_av",
          refused(lambda: wf.envs.VectorEnv(2, per_env=[{"n_av": 1}, {"n_av": 2}]), "n_av 2"))
    check("reward_refuses_bad_values", refused(lambda: wf.envs.Reward(fuel_scope="fleet"), "fuel_scope")
          and refused(lambda: wf.envs.Reward(gap_range_m=(10, 5)), "gap_range_m")
          and refused(lambda: wf.envs.Reward(w_jerk=-1), "w_jerk"))


def test_vector_env_side_by_side():
    """VectorEnv's rings stepped side by side in shared blocks of the kernel (src/core/gang.c) against the same
    environments alone: 12 rings of 22 vehicles (two blocks), every other one automated (vehicle 21 among them, the
    follower of vehicle 0 one lap ahead), 1000 actions across every run's record step (step 1000: that action the
    runs step one by one), ring 0's automated vehicles driving into their leaders (overlap repairs inside the shared
    blocks, across the ring's wrap too), ring 1's braking to rest; every observation and reward, and at the end every
    run's positions and speeds, the same bits, on 1 and 2 threads (RingEnv's runs keep no window fuel: their
    statistics window opens after the episode; tests/test_external.c compares every state block and summary)."""
    n, acts = 12, 1000
    per_env = [{"length_range_m": (230.0 + 3 * i, 231.0 + 3 * i)} for i in range(n)]
    kw = dict(warmup_s=2.0, horizon_s=200.0, n_av=11)
    actions = np.random.default_rng(7).uniform(-1.0, 1.0, (acts, n, 11))
    actions[:, 0], actions[:, 1] = 3.0, -3.0
    alone = [wf.envs.RingEnv(**kw, **per_env[i]) for i in range(n)]
    for i, e in enumerate(alone):
        e.reset(seed=30 + i)
    ref = []
    for u in actions:
        rows = [e.step(u[i]) for i, e in enumerate(alone)]
        ref.append((np.stack([r[0] for r in rows]), np.array([r[1] for r in rows])))
    keys = ("x_m", "v_mps")
    final = [{k: e.sim.state()[k].copy() for k in keys} for e in alone]
    # a repaired follower stands at its leader's rear: vehicle 21 (the last row) behind vehicle 0 too
    repaired = min(o[0][0, 0, 2] for o in ref) == 0.0 and min(o[0][0, -1, 2] for o in ref) == 0.0
    for e in alone:
        e.close()
    for threads in (1, 2):
        venv = wf.envs.VectorEnv(n, threads=threads, thread_check=0, per_env=per_env, **kw)
        venv.reset(seed=30)
        bad = [k for k, u in enumerate(actions) if (lambda o: o[0].tobytes() != ref[k][0].tobytes()
                                                    or o[1].tobytes() != ref[k][1].tobytes())(venv.step(u))]
        same = all(venv.envs[i].sim.state()[k].tobytes() == final[i][k].tobytes() for i in range(n) for k in keys)
        gang = venv.side_by_side
        check(f"vector_env_side_by_side_equals_alone_threads_{threads}",
              not bad and same and gang == acts - 1 and repaired, (bad[:5], same, gang, repaired))
        venv.close()
    # A refused command (infinite) inside the shared blocks: that run fails untouched, the others step as alone.
    envs = [wf.envs.RingEnv(**per_env[i]) for i in range(6)]
    twins = [wf.envs.RingEnv(**per_env[i]) for i in range(6)]
    for i, e in enumerate(envs + twins):
        e.reset(seed=50 + i % 6)
    batch = wf.batch.RlBatch([e.sim for e in envs], ["av"] * 6, wf.envs.Reward(), 1, 0.1)
    u = np.full(6, 0.5)
    u[2] = np.inf
    try:
        batch.step(u, 2)
        msg = ""
    except wf.WavefuelError as e:
        msg = str(e)
    t_before = twins[2].sim.t
    for i in (0, 1, 3, 4, 5):
        twins[i].step(np.array([0.5]))
    same = all(envs[i].sim.state()["x_m"].tobytes() == twins[i].sim.state()["x_m"].tobytes() for i in range(6))
    same &= envs[2].sim.t == t_before
    # the next call steps all six: run 2's reward is its own action's (nothing of the refused call is left)
    _, reward, _ = batch.step(np.full(6, 0.5), 2)
    want = np.array([twins[i].step(np.array([0.5]))[1] for i in range(6)])
    check("vector_env_side_by_side_refused_command", msg.startswith("run 2 of the batch: ") and "command 0 is inf"
          in msg and same and batch.gang_calls() == 2
          and reward.tobytes() == want.tobytes(), (msg, same, batch.gang_calls(), reward - want))
    batch.close()
    for e in envs + twins:
        e.close()


def test_sims_batch():
    """The library's batch calls (engine.h: wf_sims_set_actions, wf_sims_step on 2 threads, wf_sims_observe) on two
    rings of different lengths and seeds against each run stepped alone through Simulation."""
    import ctypes as C
    lib = wf._lib.lib
    d = dict(RING, fleet=dict(RING["fleet"], drivers=[RING["fleet"]["drivers"][0],
                                                      dict(RING["fleet"]["drivers"][1], model="external")]))
    scen = [dict(d, seed=s, road={"length_m": L}) for s, L in ((3, 600.0), (4, 650.0))]
    batch = [wf.Simulation(wf.Scenario.from_dict(x), threads=1) for x in scen]
    alone = [wf.Simulation(wf.Scenario.from_dict(x), threads=1) for x in scen]
    for sim in batch + alone:
        sim.step(1)
    ptrs = (C.c_void_p * 2)(*[s._ptr.value for s in batch])
    groups = np.array([1, 1], dtype=np.uintp)
    errs, err = (wf._lib.WfError * 2)(), wf._lib.WfError()
    obs = np.empty((12, 3))
    rng = np.random.default_rng(5)
    same, rcs = True, 0
    for k in range(50):
        u = rng.uniform(-2.0, 2.0, 12)
        rcs |= lib.wf_sims_set_actions(ptrs, 2, groups.ctypes.data, u.ctypes.data, 12, C.byref(err))
        rcs |= lib.wf_sims_step(ptrs, 2, 3, 2, C.addressof(errs))
        rcs |= lib.wf_sims_observe(ptrs, 2, groups.ctypes.data, obs.ctypes.data, 12, C.byref(err))
        for i, sim in enumerate(alone):
            sim.set_actions("av", u[6 * i:6 * i + 6])
            sim.step(3)
            same &= sim.observe("av").tobytes() == obs[6 * i:6 * i + 6].tobytes()
    same &= all(a.state()["x_m"].tobytes() == b.state()["x_m"].tobytes() for a, b in zip(batch, alone))
    check("sims_batch_equals_runs_alone", same and rcs == 0, rcs)
    rc = lib.wf_sims_set_actions(ptrs, 2, groups.ctypes.data, np.zeros(11).ctypes.data, 11, C.byref(err))
    check("sims_batch_refuses_count", rc == 2 and "12 vehicles on the road, got 11 rows" in err.msg.decode(),
          err.msg)


def ref_scenario(kw, per_env, seed):
    """The scenario of a RingEnv's first episode after reset(seed)."""
    env = wf.envs.RingEnv(**kw, **per_env)
    env.reset(seed=seed)
    d = env.scenario_dict
    env.close()
    return d


def main():
    with tempfile.TemporaryDirectory() as tmp:
        test_idm_from_python(tmp)
        test_refusals()
        test_ring_env()
        test_actions_clipped()
        test_trajectory_env(tmp)
        test_reward_terms()
        test_vector_env(tmp)
        test_vector_env_side_by_side()
        test_sims_batch()
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
