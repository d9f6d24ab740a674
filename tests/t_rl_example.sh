#!/usr/bin/env bash
# Smoke test of the reinforcement-learning example (examples/rl/, README.md): a few PPO updates on 20 s windows of
# the synthetic stop-and-go trace (no drive cycle, no learning claim), then the evaluation on another synthetic
# trace. Checks that the trace generator follows its formula (recomputed here), that the policy after two updates
# still imitates the acc law (src/models/cf/acc.c's law written again in numpy), and that the evaluation's
# all-human platoon fuel and distance equal a plain Simulation of the same scenario, and that the exported network
# (`model: mlp`) gives the torch policy's action within 1e-12. Skipped without torch.
set -u
cd "$(dirname "$0")/.." || exit 1
PY=/usr/bin/python3
if ! $PY -c 'import torch' 2>/dev/null; then
  echo "SKIP t_rl_example: torch not importable (tools/install-deps.sh rl)"; exit 0
fi
make --no-print-directory -s python BUILD=${BUILD:-build} >/dev/null ||
  { echo "FAIL python_build: make python"; exit 1; }
export PYTHONPATH="$PWD/python" WAVEFUEL_LIB="$PWD/lib/libwavefuel.so"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

# The generator against its docstring's formula, written again here.
if $PY - "$tmp/sg.csv" <<'PY' >"$tmp/gen.log" 2>&1
import subprocess, sys
import numpy as np
out = sys.argv[1]
subprocess.run([sys.executable, "examples/rl/stop_and_go.py", "--seed", "7", "--waves", "3", "-o", out], check=True,
               stdout=subprocess.DEVNULL)
t, v = np.loadtxt(out, delimiter=",", skiprows=1).T
rng = np.random.default_rng(7)
s = rng.uniform(12, 25)
ref = [s] * 30
for _ in range(3):
    P, lo, nxt = rng.uniform(40, 100), rng.uniform(0, 6), rng.uniform(12, 25)
    for k in range(int(np.ceil(P))):
        if k >= P:
            continue
        ref.append(lo + (s - lo) * (1 + np.cos(2 * np.pi * k / P)) / 2 if k < P / 2
                   else lo + (nxt - lo) * (1 + np.cos(2 * np.pi * k / P)) / 2)
    s = nxt
ref.append(s)
assert np.array_equal(t, np.arange(len(ref))), (len(t), len(ref))
assert np.allclose(v, ref, rtol=0, atol=1e-12), np.abs(v - ref).max()
assert np.abs(np.diff(v)).max() < 2.0
PY
then ok rl_stop_and_go_formula; else ko rl_stop_and_go_formula "$(tail -3 "$tmp/gen.log")"; fi

start=$SECONDS
if $PY examples/rl/train.py -o "$tmp/run" --traces stop_and_go:1 --iterations 2 --windows 1 --window-s 20 \
     --imitation-steps 200 --imitate '' --epochs 2 --minibatch 64 --select-every 1 >"$tmp/train.log" 2>&1 &&
   [ -s "$tmp/run/policy.pt" ] && [ -s "$tmp/run/policy_init.pt" ]; then ok rl_train_runs
else ko rl_train_runs "$(tail -5 "$tmp/train.log")"; fi

if $PY - "$tmp/run/policy_last.pt" <<'PY' >"$tmp/policy.log" 2>&1
import sys
import numpy as np
sys.path.insert(0, "examples/rl")
from policy import load
p, info = load(sys.argv[1])
assert info["iterations"] == 2 and len(info["log"]) == 2 and len(info["validation"]) == 3, info
rng = np.random.default_rng(0)
v = rng.uniform(0, 25, 500)
rows = np.column_stack([v, v + rng.uniform(-2, 2, 500), 4 + 1.5 * v + rng.uniform(-3, 3, 500)])
acc = np.minimum(0.4 * (rows[:, 2] - 2.0 - 1.1 * rows[:, 0]) + 0.8 * (rows[:, 1] - rows[:, 0]), 0.4 * (30 - rows[:, 0]))
err = np.sqrt(np.mean((p.act(rows) - np.clip(acc, -3, 3)) ** 2))
assert err < 0.5, f"rms {err} m/s^2 from the acc law"
print("rms from the acc law", err)
PY
then ok rl_policy_imitates_acc; else ko rl_policy_imitates_acc "$(tail -3 "$tmp/policy.log")"; fi

# The exported network (model: mlp) evaluated by the library against the torch policy's mean action.
if $PY - "$tmp/run/policy.pt" "$tmp/policy_mlp.h5" <<'PY' >"$tmp/export.log" 2>&1
import sys
import numpy as np
import wavefuel
sys.path.insert(0, "examples/rl")
from policy import export, load
p, _ = load(sys.argv[1])
export(p, sys.argv[2])
rng = np.random.default_rng(1)
rows = np.column_stack([rng.uniform(0, 35, 20000), rng.uniform(0, 35, 20000), rng.uniform(0, 200, 20000)])
d = np.abs(wavefuel.Network(sys.argv[2]).evaluate(rows) - p.act(rows)).max()
assert d <= 1e-12, d
print("max difference", d)
PY
then ok rl_export_equals_torch; else ko rl_export_equals_torch "$(tail -3 "$tmp/export.log")"; fi

if $PY examples/rl/evaluate.py "$tmp/run/policy.pt" -o "$tmp/eval" --traces stop_and_go:2 --seeds 3 --horizon-s 60 \
     >"$tmp/eval.log" 2>&1 && [ -s "$tmp/eval/evaluation.png" ]; then ok rl_evaluate_runs
else ko rl_evaluate_runs "$(tail -5 "$tmp/eval.log")"; fi

# The evaluation's platoon totals against a plain Simulation of the same all-human scenario: the fuel of the
# vehicles from index 2 back, integrated from fuel_rate_gps step by step, and their distance.
if $PY - "$tmp/eval/evaluation.json" <<'PY' >"$tmp/check.log" 2>&1
import json, sys
import numpy as np
import wavefuel
sys.path.insert(0, "examples/rl")
import platoon
row = json.load(open(sys.argv[1]))["rows"][0]
t, v = platoon.load_trace("stop_and_go:2", "")
env = platoon.PlatoonEnv((t[t <= 60], v[t <= 60]), humans_only=True)
env.np_random = np.random.default_rng(3)
sim = wavefuel.Simulation(wavefuel.Scenario.from_dict(env._scenario()), threads=1)
sim.step(int(round(env._fill_s() / env.dt_s)))
x0 = np.array(sim.state()["x_m"])
fuel = np.zeros(20)
for _ in range(int(round(env.horizon_s / env.dt_s))):
    sim.step(1)
    fuel += sim.state()["fuel_rate_gps"] * env.dt_s
x1 = np.array(sim.state()["x_m"])
f, d = fuel[2:].sum(), (x1 - x0)[2:].sum()
assert abs(f - row["human_fuel_g"]) < 1e-9 * f and abs(d - row["human_dist_m"]) < 1e-9 * d, (f, d, row)
assert all(np.isfinite(row[f"{c}_fuel_g"]) and row[f"{c}_fuel_g"] > 0 for c in ("human", "acc", "policy")), row
print(f, d)
PY
then ok rl_evaluation_totals; else ko rl_evaluation_totals "$(tail -3 "$tmp/check.log")"; fi
echo "# t_rl_example: $((SECONDS - start)) s"
