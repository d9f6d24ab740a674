"""Learned controllers, `model: mlp` (docs/controllers.md): prints PASS/FAIL lines.

- The library's network (wavefuel.Network, the code a run uses) equals the numpy forward pass (wavefuel.mlp_forward)
  within 1e-12 on random networks (depths 1 to 5, widths 1 to 200, mixed activations, random normalisation, output
  scaling and clipping) and random rows; with any thread count and any batch the same bits; PyTorch's float64
  forward (when torch is importable: skipped otherwise) agrees within 1e-12, and a torch nn.Sequential exports.
- Runs: a ring and a corridor with mlp groups give the same bits with 1 and 2 threads; a run interrupted and resumed
  (`wavefuel run --resume`) equals the uninterrupted one; a network computing a linear law gives the bits of an
  external group commanded with the same law computed in numpy; a constant set-speed network gives the bits of an
  `acc` group with that set speed; the commands of every step equal the numpy forward pass of the observations.
- Refusals in a run: commands set on an mlp group; a network whose output overflows."""
import os
import subprocess
import sys
import tempfile

import h5py
import numpy as np

import wavefuel as wf

failures = 0
BIN = os.environ.get("WAVEFUEL_BIN", "bin/wavefuel")


def check(name, ok, detail=""):
    global failures
    print(("PASS " if ok else "FAIL ") + name + ("" if ok else ": " + str(detail)))
    sys.stdout.flush()
    failures += not ok


def random_network(rng, depth, width, acts):
    sizes = [3] + [int(rng.integers(1, width + 1)) for _ in range(depth - 1)] + [1]
    layers = [(rng.normal(size=(sizes[k + 1], sizes[k])) / np.sqrt(sizes[k]), rng.normal(size=sizes[k + 1]))
              for k in range(depth)]
    return layers, [str(rng.choice(acts)) for _ in range(depth)]


def random_rows(rng, n):
    rows = np.column_stack([rng.uniform(0, 35, n), rng.uniform(0, 35, n), rng.exponential(30, n)])
    rows[:5] = [[0, 0, 0], [30, 0, 1e5], [0, 30, 0.1], [1e-3, 1e-3, 1e-3], [12.5, 12.5, 20.0]]
    return rows


def test_against_numpy(tmp):
    rng = np.random.default_rng(17)
    worst, cases, bits = 0.0, 0, True
    for depth in (1, 2, 3, 5):
        for width in (1, 8, 64, 200):
            for acts in (["tanh"], ["relu"], ["identity"], ["tanh", "relu", "identity"]):
                layers, a = random_network(rng, depth, width, acts)
                lo = float(rng.uniform(-5, 0)) if rng.random() < 0.5 else None
                path = os.path.join(tmp, "r.h5")
                wf.export_mlp(path, layers, activations=a, input_mean=rng.uniform(0, 20, 3),
                              input_std=rng.uniform(0.5, 20, 3), output=str(rng.choice(wf.mlp.OUTPUTS)),
                              output_scale=float(rng.uniform(-4, 4)), output_offset=float(rng.normal()),
                              output_min=lo, output_max=None if lo is None else lo + float(rng.uniform(0.5, 8)))
                rows = random_rows(rng, 1001)
                with wf.Network(path) as net:
                    c = net.evaluate(rows)
                    # Threads, batch position and batch size change no bit.
                    bits &= np.array_equal(c, net.evaluate(rows, threads=2)) and \
                        np.array_equal(c[7:8], net.evaluate(rows[7:8])) and \
                        np.array_equal(c[3:10], net.evaluate(rows[3:10], threads=3))
                ref = wf.mlp_forward(path, rows)
                worst = max(worst, float(np.max(np.abs(c - ref) / np.maximum(1.0, np.abs(ref)))))
                cases += 1
    check("mlp_equals_numpy_1e-12", worst <= 1e-12, worst)
    check("mlp_same_bits_any_threads_and_batch", bits)
    print(f"  {cases} random networks x 1001 rows: largest difference {worst:.2e} (relative, or absolute below 1)")


def test_against_torch(tmp):
    try:
        import torch
    except ImportError:
        print("SKIP mlp_equals_torch: torch is not installed")
        return
    torch.manual_seed(5)
    rng = np.random.default_rng(5)
    worst = 0.0
    for hidden, act in ((64, torch.nn.Tanh), (32, torch.nn.ReLU), (7, torch.nn.Identity)):
        model = torch.nn.Sequential(torch.nn.Linear(3, hidden), act(), torch.nn.Linear(hidden, hidden), act(),
                                    torch.nn.Linear(hidden, 1)).double()
        path = os.path.join(tmp, "torch.h5")
        wf.export_mlp(path, model)
        rows = random_rows(rng, 500)
        with torch.no_grad():
            ref = model(torch.from_numpy(rows)).numpy()[:, 0]
        c = wf.Network(path).evaluate(rows)
        worst = max(worst, float(np.max(np.abs(c - ref) / np.maximum(1.0, np.abs(ref)))))
    check("mlp_equals_torch_1e-12", worst <= 1e-12, worst)
    # A float32 module exports as float64 of its float32 weights; an unsupported layer is refused.
    model32 = torch.nn.Sequential(torch.nn.Linear(3, 4), torch.nn.Tanh(), torch.nn.Linear(4, 1))
    wf.export_mlp(path, model32)
    w = wf.read_mlp(path)["layers"][0][0]
    check("mlp_torch_float32_exported", w.dtype == np.float64 and np.array_equal(
        w, model32[0].weight.detach().numpy().astype(np.float64)))
    try:
        wf.export_mlp(path, torch.nn.Sequential(torch.nn.Linear(3, 4), torch.nn.Sigmoid(), torch.nn.Linear(4, 1)))
        check("mlp_torch_unsupported_refused", False, "no error")
    except ValueError as e:
        check("mlp_torch_unsupported_refused", "Sigmoid" in str(e), e)


RING = {
    "name": "mlp_ring", "seed": 21, "road": {"length_m": 4000},
    "time": {"duration_s": 60, "dt_s": 0.1, "output_interval_s": 1.0, "warmup_s": 10},
    "fleet": {"vehicles": 300, "placement": "interleaved", "classes": [{"class": "midsize_sedan", "fraction": 1.0}],
              "drivers": [{"name": "human", "model": "idm", "fraction": 0.5, "noise_mps2": 0.3},
                          {"name": "av", "model": "mlp", "network": "NET", "fraction": 0.5, "noise_mps2": 0.1}]},
    "initial": {"state": "equilibrium", "jitter_m": 0.5},
    "output": {"trajectories": True, "trajectory_interval_s": 1.0},
}

CORRIDOR = {
    "name": "mlp_corridor", "seed": 4, "road": {"type": "corridor", "length_m": 3000},
    "time": {"duration_s": 300, "dt_s": 0.1, "output_interval_s": 5.0, "warmup_s": 0},
    "fleet": {"placement": "interleaved", "classes": [{"class": "midsize_sedan", "fraction": 1.0}],
              "drivers": [{"name": "human", "model": "idm", "fraction": 0.7, "noise_mps2": 0.2},
                          {"name": "av", "model": "mlp", "network": "NET", "fraction": 0.3}]},
    "corridor": {"inflow": {"flow_vph": 2000}},
    "output": {"trajectories": False},
}


def with_group(d, **av):
    d = dict(d, fleet=dict(d["fleet"]))
    d["fleet"]["drivers"] = [d["fleet"]["drivers"][0], dict(d["fleet"]["drivers"][1], **av)]
    if "network" in d["fleet"]["drivers"][1] and d["fleet"]["drivers"][1]["model"] != "mlp":
        del d["fleet"]["drivers"][1]["network"]
    return d


def datasets(path, skip_model=False):
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            skip = name.startswith("meta/") or (skip_model and name.startswith("drivers/model"))
            if isinstance(obj, h5py.Dataset) and not skip:
                x = np.asarray(obj[()])
                out[name] = (x.dtype.str, x.shape, x.tobytes()) if x.dtype.kind in "fiub" else repr(x.tolist())
        f.visititems(visit)
    return out


def same(a, b):
    return [n for n in set(a) | set(b) if a.get(n) != b.get(n)]


def run(d, out, threads):
    with wf.Simulation(wf.Scenario.from_dict(d, path=os.path.join(os.path.dirname(out), "s.yaml")),
                       threads=threads, output=out, force=True) as sim:
        sim.run()
    return datasets(out)


def policy(tmp):
    """A 2 x 16 tanh policy: a bounded acceleration that brakes at small gaps and closing speeds."""
    rng = np.random.default_rng(8)
    layers = [(rng.normal(size=(16, 3)) * 0.5, rng.normal(size=16) * 0.1),
              (rng.normal(size=(16, 16)) * 0.3, rng.normal(size=16) * 0.1), (rng.normal(size=(1, 16)) * 0.3, [0.0])]
    path = os.path.join(tmp, "policy.h5")
    return wf.export_mlp(path, layers, activations="tanh", input_mean=[15, 15, 20], input_std=[10, 10, 20],
                         output_scale=1.5, output_min=-3, output_max=2)


def test_threads_and_resume(tmp):
    net = policy(tmp)
    for name, base in (("ring", RING), ("corridor", CORRIDOR)):
        d = with_group(base, network=net)
        a = run(d, os.path.join(tmp, f"{name}1.h5"), 1)
        b = run(d, os.path.join(tmp, f"{name}2.h5"), 2)
        n_av = wf.read(os.path.join(tmp, f"{name}1.h5"))
        check(f"mlp_{name}_same_bits_1_and_2_threads", a == b and len(a) > 30, same(a, b)[:5])
        # Interrupted after a third of the run (a checkpoint), resumed by the CLI: the uninterrupted bits.
        part = os.path.join(tmp, f"{name}_resumed.h5")
        sc = wf.Scenario.from_dict(d, path=os.path.join(tmp, "s.yaml"))
        with wf.Simulation(sc, threads=2, output=part, force=True) as sim:
            sim.step(sc.n_steps // 3 + 7)
            sim.finish()
        r = subprocess.run([BIN, "run", "--resume", part, "-q", "--threads", "1"], capture_output=True, text=True)
        c = datasets(part) if r.returncode == 0 else {}
        check(f"mlp_{name}_resume_equals_uninterrupted", r.returncode == 0 and c == a, (r.stderr, same(a, c)[:5]))
        models = list(n_av["drivers/model"])
        check(f"mlp_{name}_model_recorded", models == ["idm", "mlp"], models)


def test_linear_law(tmp):
    """a = b + w0 v + w1 v_lead + w2 gap: an identity layer, against an external group commanded from numpy with
    the same law evaluated in the same order (((b + w0 v) + w1 v_lead) + w2 gap): every dataset bit for bit."""
    k_gap, k_dv, T, s0 = 0.2, 0.6, 1.2, 2.0
    w = np.array([[-k_gap * T - k_dv, k_dv, k_gap]])
    b = np.array([-k_gap * s0])
    path = wf.export_mlp(os.path.join(tmp, "linear.h5"), [(w, b)], activations=["identity"])
    d = with_group(RING, network=path)
    d["fleet"] = dict(d["fleet"], vehicles=60)
    d["road"] = {"length_m": 1200}
    ref = os.path.join(tmp, "linear_mlp.h5")
    run(d, ref, 2)
    ext = with_group(d, model="external")
    out = os.path.join(tmp, "linear_ext.h5")
    steps, worst = 0, 0.0
    net = wf.read_mlp(path)
    with wf.Simulation(wf.Scenario.from_dict(ext, path=os.path.join(tmp, "s.yaml")), threads=2, output=out,
                       force=True) as sim:
        while not sim.done:
            obs = sim.observe("av")
            u = ((b[0] + w[0, 0] * obs[:, 0]) + w[0, 1] * obs[:, 1]) + w[0, 2] * obs[:, 2]
            worst = max(worst, float(np.max(np.abs(u - wf.mlp_forward(net, obs)))))
            sim.set_actions("av", u)
            sim.step(1)
            steps += 1
    a, c = datasets(ref, skip_model=True), datasets(out, skip_model=True)
    check("mlp_linear_law_equals_external_from_numpy", a == c and steps == 601, (steps, same(a, c)[:5]))
    check("mlp_linear_law_forward_agrees", worst <= 1e-12, worst)


def test_constant_speed(tmp):
    """A set-speed network with zero weights and bias 24 m/s follows the acc law with v0 = 24 m/s: the bits of an
    `acc` group with v0_mps 24 (the same parameters, so the same initial conditions and corridor entries)."""
    path = wf.export_mlp(os.path.join(tmp, "const.h5"), [(np.zeros((4, 3)), np.zeros(4)), (np.zeros((1, 4)), [24.0])],
                         activations=["relu", "identity"], output="speed")
    d = with_group(CORRIDOR, network=path, params={"v0_mps": 24})
    a = run(d, os.path.join(tmp, "c1.h5"), 2)
    b = run(with_group(d, model="acc"), os.path.join(tmp, "c2.h5"), 2)
    a = {k: v for k, v in a.items() if not k.startswith("drivers/model")}
    b = {k: v for k, v in b.items() if not k.startswith("drivers/model")}
    check("mlp_constant_speed_equals_acc", a == b and len(a) > 30, same(a, b)[:5])


def test_acc_as_relu_network(tmp):
    """The acc law, min(a_gap, a_speed) with a_gap = k_gap (gap - s0 - T v) + k_dv (v_lead - v) and a_speed =
    k_v (v0 - v), written exactly as a ReLU network: a_gap - relu(a_gap - a_speed), a_gap = relu(a_gap) -
    relu(-a_gap). Its corridor run equals the `acc` group's up to rounding (the network adds the terms in another
    order): every vehicle's trip fuel and distance within 1e-9 relative."""
    k_gap, k_dv, T, s0, v0, k_v = 0.4, 0.8, 1.1, 2.0, 30.0, 0.4
    a_gap = np.array([-k_gap * T - k_dv, k_dv, k_gap]), -k_gap * s0
    a_speed = np.array([-k_v, 0.0, 0.0]), k_v * v0
    w0 = np.array([a_gap[0], -a_gap[0], a_gap[0] - a_speed[0]])
    b0 = np.array([a_gap[1], -a_gap[1], a_gap[1] - a_speed[1]])
    path = wf.export_mlp(os.path.join(tmp, "acc_relu.h5"), [(w0, b0), (np.array([[1.0, -1.0, -1.0]]), [0.0])],
                         activations=["relu", "identity"])
    d = with_group(CORRIDOR, network=path)
    a, b = (os.path.join(tmp, f"accnet{k}.h5") for k in (1, 2))
    run(d, a, 2)
    run(with_group(d, model="acc"), b, 2)
    worst, n = 0.0, 0
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        for col in ("fuel", "distance"):
            x, y = fa["trips/" + col][()], fb["trips/" + col][()]
            ok = x.shape == y.shape and x.size > 50
            n = x.size if ok else 0
            worst = max(worst, float(np.max(np.abs(x - y) / np.abs(y)))) if ok else np.inf
    check("mlp_acc_as_relu_network_equals_acc", worst <= 1e-9, (n, worst))
    print(f"  {n} trips: largest relative difference {worst:.1e}")


def test_commands_each_step(tmp):
    """The acceleration an mlp vehicle applies (no noise, limits wider than the output) is the numpy forward pass of
    its observation at the step's start, at every step."""
    net = policy(tmp)
    d = with_group(RING, network=net, noise_mps2=0.0)
    d["fleet"] = dict(d["fleet"], vehicles=40)
    d["road"] = {"length_m": 800}
    d["time"] = dict(d["time"], fused_step=False)  # the fleet's a_mps2 at every step
    worst, steps = 0.0, 0
    ref = wf.read_mlp(net)
    with wf.Simulation(wf.Scenario.from_dict(d, path=os.path.join(tmp, "s.yaml")), threads=2) as sim:
        group = np.array(sim.state()["group_id"]) == 1
        while steps < 300:
            u = wf.mlp_forward(ref, sim.observe("av"))
            sim.step(1)
            a = np.array(sim.state()["a_mps2"])[group]
            worst = max(worst, float(np.max(np.abs(a - u))))
            steps += 1
    check("mlp_applied_accel_equals_numpy", worst <= 1e-12, worst)


def test_run_refusals(tmp):
    net = policy(tmp)
    with wf.Simulation(wf.Scenario.from_dict(with_group(RING, network=net), path=os.path.join(tmp, "s.yaml"))) as sim:
        try:
            sim.set_actions("av", np.zeros(sim.group_size("av")))
            check("mlp_set_actions_refused", False, "no error")
        except wf.WavefuelError as e:
            check("mlp_set_actions_refused", "network sets them" in str(e), e)
        check("mlp_observe_allowed", sim.observe("av").shape == (150, 3))
    # Finite weights whose output overflows: the run stops with a message naming the network and the vehicle.
    big = wf.export_mlp(os.path.join(tmp, "big.h5"), [(np.full((2, 3), 1e300), np.zeros(2)),
                                                     (np.full((1, 2), 1e300), [0.0])], activations="identity")
    with wf.Simulation(wf.Scenario.from_dict(with_group(RING, network=big), path=os.path.join(tmp, "s.yaml"))) as sim:
        try:
            sim.step(1)
            check("mlp_overflow_refused", False, "no error")
        except wf.WavefuelError as e:
            check("mlp_overflow_refused", e.code == 2 and big in str(e) and "gives inf" in str(e), e)


def test_shipped_network(tmp):
    """scenarios/data/follower_stopper_mlp.h5 is what examples/mlp/make_policy.py writes (values within 1e-9: a
    LAPACK other than this machine's may round the least-squares fit differently)."""
    out = os.path.join(tmp, "regenerated.h5")
    r = subprocess.run([sys.executable, "examples/mlp/make_policy.py", out], capture_output=True, text=True)
    ok = r.returncode == 0
    if ok:
        a, b = wf.read_mlp(out), wf.read_mlp("scenarios/data/follower_stopper_mlp.h5")
        ok = [x[2] for x in a["layers"]] == [x[2] for x in b["layers"]] and a["output"] == b["output"] == "speed"
        for (wa, ba, _), (wb, bb, _) in zip(a["layers"], b["layers"]):
            ok = ok and wa.shape == wb.shape and np.allclose(wa, wb, rtol=1e-9, atol=1e-9) and \
                np.allclose(ba, bb, rtol=1e-9, atol=1e-9)
    check("mlp_shipped_network_regenerates", ok, r.stderr)


TESTS = (test_shipped_network, test_against_numpy, test_against_torch, test_threads_and_resume, test_linear_law,
         test_constant_speed, test_acc_as_relu_network, test_commands_each_step, test_run_refusals)


def main():
    with tempfile.TemporaryDirectory() as tmp:
        for test in TESTS:  # each in the same scratch directory
            test(tmp)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
