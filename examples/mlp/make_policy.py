#!/usr/bin/env python3
"""Writes the network of scenarios/sugiyama_mlp.yaml: a small tanh network (3 -> 64 -> 1) that imitates
FollowerStopper's commanded speed (Stern et al. 2018; docs/controllers.md) with U = 2.5 m/s, so that one
network-driven vehicle damps the Sugiyama ring's stop-and-go wave as the built-in controller does.

The network is fitted, not trained by reinforcement learning: the hidden layer is drawn at random from a fixed seed
and the output layer is the least-squares fit (numpy's lstsq) of the command on 40 000 random observations (own
speed and leader speed in [0, 8] m/s, gap in [0, 30] m), an extreme learning machine: deterministic and instant.
Its output is a set speed (output kind `speed`), clipped to [0, U] and followed by the acc law.

    /usr/bin/python3 examples/mlp/make_policy.py [OUT.h5]     (default: scenarios/data/follower_stopper_mlp.h5)

Needs numpy and h5py, and the wavefuel package (PYTHONPATH=python from the checkout, after `make python`)."""
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "python"))
import wavefuel  # noqa: E402

U_MPS = 2.5
HIDDEN = 64
V_MAX_MPS, GAP_MAX_M = 8.0, 30.0  # the sampled observations


def follower_stopper_command(v, vl, gap, U=U_MPS, dx=(4.5, 5.25, 6.0), d=(1.5, 1.0, 0.5)):
    """FollowerStopper's commanded speed (m/s), docs/controllers.md, with its default boundaries."""
    dv2 = np.minimum(vl - v, 0.0) ** 2
    x1, x2, x3 = (dx[k] + dv2 / (2.0 * d[k]) for k in range(3))
    w = np.minimum(np.maximum(vl, 0.0), U)
    return np.where(gap <= x1, 0.0, np.where(gap <= x2, w * (gap - x1) / (x2 - x1),
                    np.where(gap <= x3, w + (U - w) * (gap - x2) / (x3 - x2), U)))


def fit(target, hidden=(HIDDEN,), seed=2018, n=40000, v_max_mps=V_MAX_MPS, gap_max_m=GAP_MAX_M):
    """Layers [(weight, bias)] of a tanh network whose hidden layers are drawn at random (seed) and whose output
    layer is the least-squares fit of target(v, v_lead, gap) on n random observations; and those observations and
    targets. The inputs are normalised by MEAN and STD scaled to the sampled ranges (returned too)."""
    rng = np.random.default_rng(seed)
    rows = np.column_stack([rng.uniform(0, v_max_mps, n), rng.uniform(0, v_max_mps, n), rng.uniform(0, gap_max_m, n)])
    y = target(rows[:, 0], rows[:, 1], rows[:, 2])
    mean = np.array([v_max_mps / 2, v_max_mps / 2, gap_max_m / 2])
    layers, h, width = [], (rows - mean) / mean, 3
    for k, units in enumerate(hidden):
        # The first layer sees normalised inputs; deeper ones see tanh outputs: weights of variance 1 / width.
        w, b = rng.normal(0, 1.0 if k == 0 else 1.0 / np.sqrt(width), (units, width)), rng.normal(0, 1.0, units)
        layers.append((w, b))
        h, width = np.tanh(h @ w.T + b), units
    coef, *_ = np.linalg.lstsq(np.column_stack([h, np.ones(n)]), y, rcond=None)
    return layers + [(coef[None, :-1], coef[-1:])], rows, y, mean


def main():
    default = os.path.join(HERE, "..", "..", "scenarios", "data", "follower_stopper_mlp.h5")
    out = os.path.normpath(sys.argv[1] if len(sys.argv) > 1 else default)
    layers, rows, target, mean = fit(follower_stopper_command)
    wavefuel.export_mlp(out, layers, activations="tanh", input_mean=mean, input_std=mean, output="speed",
                        output_min=0.0, output_max=U_MPS)
    err = wavefuel.mlp_forward(out, rows) - target
    print(f"{out}: 3 -> {HIDDEN} -> 1 tanh, command error rms {np.sqrt(np.mean(err ** 2)):.3f} m/s, "
          f"max {np.max(np.abs(err)):.3f} m/s over the fitted observations")


if __name__ == "__main__":
    main()
