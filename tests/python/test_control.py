"""External controllers and RL environments from Python (docs/python.md, docs/controllers.md): prints PASS/FAIL lines.

- An external group driven from Python with the IDM formula (written here in numpy, from Treiber et al.'s equation,
  not through the library) gives the bits of the same group with `model: idm`: every dataset of the result files
  (those naming the model or its parameters aside) and the final state.
- RingEnv and TrajectoryEnv follow the Gymnasium API: shapes and spaces, determinism for a seed, the ring length
  drawn per episode, truncation at the horizon, the reward equal to minus the mean fuel rate recomputed here from
  the class's fuel at the observed speeds.
- Refusals: commands to a group that is not external, the wrong count, an infinite command, an unknown group."""
import os
import sys
import tempfile

import h5py
import numpy as np

import wavefuel as wf

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
    # The reward of a step: minus the mean over vehicles of the class's fuel rate at the step's start speed and
    # the acceleration (v_end - v_start) / dt, recomputed here.
    env.reset(seed=9)
    v0 = np.array(env.sim.state()["v_mps"])
    _, r, _, _, info = env.step(np.full(2, 0.5))
    v1 = np.array(env.sim.state()["v_mps"])
    want = -np.mean(wf.energy.fuel("midsize_sedan", v0, (v1 - v0) / 0.1, 0.0))
    check("ring_env_reward_recomputed", abs(r - want) <= 1e-12 * abs(want), (r, want))
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


def main():
    with tempfile.TemporaryDirectory() as tmp:
        test_idm_from_python(tmp)
        test_refusals()
        test_ring_env()
        test_trajectory_env(tmp)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
