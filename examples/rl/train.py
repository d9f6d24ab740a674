#!/usr/bin/env python3
"""Trains the platoon policy of examples/rl/ (README.md) with PPO on wavefuel.envs.TrajectoryEnv.

1. Observations of the AVs driving as `acc` on the training traces give the input normalisation (their mean and
   standard deviation, fixed from then on) and the initialisation: the policy imitates the acc law (least squares
   on those observations and on perturbed copies of them).
2. PPO: each iteration plays --windows windows of --window-s seconds cut from random training traces at random
   starts, the AVs' accelerations drawn from the Gaussian policy (one decision every 0.5 s), each AV an agent
   with its own reward (platoon.Reward: its segment's fuel, its gap bounds, its comfort); GAE, clipped
   surrogate, a value network on the same inputs.
Writes DIR/policy_init.pt (the imitation) and DIR/policy.pt (the policy, its normalisation, the run's settings and
log) after every iteration.

    PYTHONPATH=python /usr/bin/python3 examples/rl/train.py -o output/rl --minutes 12
"""
import argparse
import json
import os
import sys
import time

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import platoon  # noqa: E402
from platoon import TRAIN_TRACES, Episode, PlatoonEnv, acc_law, load_trace, windows  # noqa: E402
from policy import Policy, Value, save  # noqa: E402


def acc_observations(traces, rng, window_s, count):
    """Rows the acc AVs observe on windows of the training traces (no command: the AVs drive as acc)."""
    rows = []
    for trace in traces:
        for w in windows(trace, window_s, rng, count):
            ep = Episode(PlatoonEnv(w), seed=int(rng.integers(1, 2**31)))
            while not ep.done:
                rows.append(ep.obs.copy())
                ep.step(None)
            ep.close()
    return np.concatenate(rows)


def imitate_acc(policy, rows, rng, steps, law):
    """Least-squares fit of the policy's mean to the acc law with parameters `law` (platoon.acc_law) on the rows
    and on perturbed copies (gap x U(0.3, 3), leader speed +- U(-4, 4) m/s) so that
    the start covers states acc itself avoids. Returns the rms error."""
    pert = rows.copy()
    pert[:, 2] *= rng.uniform(0.3, 3.0, len(pert))
    pert[:, 1] = np.maximum(pert[:, 1] + rng.uniform(-4, 4, len(pert)), 0)
    x = np.concatenate([rows, pert])
    y = np.clip(acc_law(x, **law), *platoon.ACCEL_RANGE_MPS2)
    x, y = torch.as_tensor(x), torch.as_tensor(y)
    opt = torch.optim.Adam(policy.net.parameters(), lr=3e-3)
    for k in range(steps):
        idx = torch.as_tensor(rng.integers(0, len(x), min(2048, len(x))))
        loss = ((policy.mean(x[idx]) - y[idx]) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    with torch.no_grad():
        return float(((policy.mean(x).clamp(*platoon.ACCEL_RANGE_MPS2) - y) ** 2).mean().sqrt())


def validate(policy, val_windows):
    """Summed reward of the deterministic policy on fixed windows of the training traces (model selection)."""
    total = 0.0
    for w, seed in val_windows:
        ep = Episode(PlatoonEnv(w), seed=seed)
        while not ep.done:
            total += float(ep.step(policy.act(ep.obs))[1].sum())
        ep.close()
    return total


def rollout(policy, value, trace, seed):
    """One window with the Gaussian policy: per AV the arrays obs, act, logp, reward, value and the reward terms'
    sums; the last value bootstraps the truncated window."""
    ep = Episode(PlatoonEnv(trace), seed=seed)
    buf = {k: [] for k in ("obs", "act", "logp", "rew", "val")}
    terms = {"fuel": 0.0, "gap": 0.0, "comfort": 0.0}
    while not ep.done:
        obs = torch.as_tensor(ep.obs.copy())
        with torch.no_grad():
            d = policy.dist(obs)
            a = d.sample()
            buf["logp"].append(d.log_prob(a).numpy())
            buf["val"].append(value(obs).numpy())
        buf["obs"].append(ep.obs.copy())
        buf["act"].append(a.numpy())
        _, r, t = ep.step(a.numpy())
        buf["rew"].append(r)
        for k in terms:
            terms[k] += float(t[k].sum())
    with torch.no_grad():
        last = value(torch.as_tensor(ep.obs.copy())).numpy()
    ep.close()
    return {k: np.array(v) for k, v in buf.items()}, last, terms


def gae(rew, val, last, gamma, lam):
    """Advantages and returns, arrays [decisions, AVs], the window truncated (bootstrapped with `last`)."""
    adv = np.zeros_like(rew)
    run = np.zeros(rew.shape[1])
    nxt = last
    for i in range(len(rew) - 1, -1, -1):
        delta = rew[i] + gamma * nxt - val[i]
        run = delta + gamma * lam * run
        adv[i], nxt = run, val[i]
    return adv, adv + val


def ppo_update(policy, value, opt_p, opt_v, batch, args, rng):
    obs, act, logp0, adv, ret = (torch.as_tensor(batch[k]) for k in ("obs", "act", "logp", "adv", "ret"))
    adv = (adv - adv.mean()) / (adv.std() + 1e-8)
    n = len(obs)
    for _ in range(args.epochs):
        perm = rng.permutation(n)
        for s in range(0, n, args.minibatch):
            i = torch.as_tensor(perm[s:s + args.minibatch])
            ratio = (policy.dist(obs[i]).log_prob(act[i]) - logp0[i]).exp()
            loss_p = -torch.min(ratio * adv[i], ratio.clamp(1 - args.clip, 1 + args.clip) * adv[i]).mean()
            opt_p.zero_grad()
            loss_p.backward()
            torch.nn.utils.clip_grad_norm_(policy.parameters(), 0.5)
            opt_p.step()
            loss_v = ((value(obs[i]) - ret[i]) ** 2).mean()
            opt_v.zero_grad()
            loss_v.backward()
            torch.nn.utils.clip_grad_norm_(value.net.parameters(), 0.5)
            opt_v.step()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--output", required=True, help="directory for policy.pt")
    ap.add_argument("--data", default=platoon.default_data_dir(),
                    help="data directory holding cycles/*.csv (default $WAVEFUEL_DATA, else ../shared/data "
                         "next to the repository)")
    ap.add_argument("--traces", default=",".join(TRAIN_TRACES), help="training traces (default %(default)s)")
    ap.add_argument("--minutes", type=float, default=12.0, help="stop after this wall time (default 12)")
    ap.add_argument("--iterations", type=int, default=10**6, help="stop after this many PPO iterations")
    ap.add_argument("--windows", type=int, default=4, help="windows per iteration (default 4)")
    ap.add_argument("--window-s", type=float, default=300.0, help="window length, s (default 300)")
    ap.add_argument("--imitation-steps", type=int, default=1500, help="steps of the acc imitation (default 1500)")
    ap.add_argument("--imitate", default="T=2.0,k_gap=0.15,k_dv=0.5",
                    help="the acc law's parameters imitated at the start, k=v,... of platoon.acc_law (T, k_gap, "
                         "k_dv, s0, v0, k_v; others at acc's defaults; default %(default)s: a 2 s time gap with "
                         "softer gains; '' for acc itself)")
    ap.add_argument("--epochs", type=int, default=8)
    ap.add_argument("--minibatch", type=int, default=1024)
    ap.add_argument("--lr", type=float, default=1e-4, help="policy learning rate (the value's: 3x)")
    ap.add_argument("--clip", type=float, default=0.2)
    ap.add_argument("--gamma", type=float, default=0.995)
    ap.add_argument("--lam", type=float, default=0.95)
    ap.add_argument("--std", type=float, default=0.3, help="initial exploration std, m/s^2 (default 0.3)")
    ap.add_argument("--select-every", type=int, default=5,
                    help="iterations between validations of the deterministic policy on fixed training windows; "
                         "policy.pt is the best validated (default 5)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    os.makedirs(args.output, exist_ok=True)
    torch.manual_seed(args.seed)
    torch.set_num_threads(1)
    rng = np.random.default_rng(args.seed)
    names = args.traces.split(",")
    traces = [load_trace(n, args.data) for n in names]
    start = time.time()
    load0 = os.getloadavg()[0]

    rows = acc_observations(traces, rng, args.window_s, 2)
    policy = Policy(rows.mean(0), rows.std(0), args.std)
    law = {k: float(v) for k, v in (kv.split("=") for kv in args.imitate.split(",") if kv)}
    bc_rms = imitate_acc(policy, rows, rng, args.imitation_steps, law)
    value = Value(policy)
    print(f"acc imitation: {len(rows)} observations, rms error {bc_rms:.4f} m/s^2, "
          f"input mean {np.round(rows.mean(0), 3)}, std {np.round(rows.std(0), 3)} ({time.time() - start:.0f} s)",
          flush=True)
    opt_p = torch.optim.Adam(policy.parameters(), lr=args.lr)
    opt_v = torch.optim.Adam(value.net.parameters(), lr=3 * args.lr)
    log = []
    info = {"args": vars(args), "traces": names, "imitation_rms_mps2": bc_rms, "log": log, "iterations": 0,
            "wall_s": time.time() - start, "load_start": load0}
    save(os.path.join(args.output, "policy_init.pt"), policy, info)
    val_windows = [(w, int(rng.integers(1, 2**31))) for tr in traces for w in windows(tr, args.window_s, rng, 1)]
    best = validate(policy, val_windows)
    info.update(best_iteration=0, best_validation=best, validation=[[0, best]])
    save(os.path.join(args.output, "policy.pt"), policy, info)
    print(f"validation of the imitation: {best:.2f}", flush=True)
    it = 0
    while it < args.iterations and time.time() - start < 60 * args.minutes:
        parts, sums = [], {"fuel": 0.0, "gap": 0.0, "comfort": 0.0}
        n_dec = 0
        for k in range(args.windows):
            trace = traces[int(rng.integers(len(traces)))]
            w = windows(trace, args.window_s, rng, 1)[0]
            buf, last, terms = rollout(policy, value, w, int(rng.integers(1, 2**31)))
            buf["adv"], buf["ret"] = gae(buf["rew"], buf["val"], last, args.gamma, args.lam)
            parts.append({k2: v.reshape(-1, *v.shape[2:]) for k2, v in buf.items()})
            n_dec += buf["rew"].size
            for k2 in sums:
                sums[k2] += terms[k2]
        batch = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        ppo_update(policy, value, opt_p, opt_v, batch, args, rng)
        it += 1
        row = {"iteration": it, "wall_s": round(time.time() - start, 1), "samples": int(n_dec),
               **{k: round(v / n_dec, 5) for k, v in sums.items()},
               "std_mps2": round(float(policy.log_std.exp()), 4)}
        log.append(row)
        print(json.dumps(row), flush=True)
        info.update(wall_s=time.time() - start, iterations=it, load_start=load0, load_end=os.getloadavg()[0])
        if it % args.select_every == 0:
            score = validate(policy, val_windows)
            info["validation"].append([it, score])
            print(f"validation at iteration {it}: {score:.2f} (best {best:.2f} at {info['best_iteration']})",
                  flush=True)
            if score > best:
                best = score
                info.update(best_iteration=it, best_validation=best)
                save(os.path.join(args.output, "policy.pt"), policy, info)
        save(os.path.join(args.output, "policy_last.pt"), policy, info)
    print(f"{it} iterations in {time.time() - start:.0f} s (load average {load0:.2f} at the start, "
          f"{os.getloadavg()[0]:.2f} at the end): {os.path.join(args.output, 'policy.pt')} (iteration "
          f"{info['best_iteration']})")


if __name__ == "__main__":
    main()
