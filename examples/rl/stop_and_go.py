#!/usr/bin/env python3
"""A synthetic stop-and-go speed trace (time_s, speed_mps at 1 Hz), drawn from a seed, for examples/rl/.

The trace is `waves` waves after a cruise of `lead_s` s at the first wave's top speed. Wave k starts at speed
s_k, slows to a low speed l_k and speeds up to s_(k+1), each half a raised cosine of duration P_k / 2:
    v(tau) = l_k + (s_k - l_k) (1 + cos(2 pi tau / P_k)) / 2,          0 <= tau < P_k / 2
    v(tau) = l_k + (s_(k+1) - l_k) (1 + cos(2 pi tau / P_k)) / 2,  P_k / 2 <= tau < P_k
with P_k ~ U(40, 100) s, l_k ~ U(0, 6) m/s and s_k ~ U(12, 25) m/s drawn by numpy's default_rng(seed) in that
order per wave (s_0 first). The speed and its derivative are continuous; the largest acceleration is
(s - l) pi / P_k, below 2 m/s^2. The trace ends at s_waves.

    /usr/bin/python3 examples/rl/stop_and_go.py --seed 1 -o output/rl/stop_and_go_1.csv
"""
import argparse
import os

import numpy as np


def stop_and_go(seed, waves=12, lead_s=30):
    """(time_s, speed_mps) at 1 Hz of the trace of the module docstring."""
    rng = np.random.default_rng(seed)
    top = rng.uniform(12.0, 25.0)
    pieces = [np.full(lead_s, top)]
    for _ in range(waves):
        period_s = rng.uniform(40.0, 100.0)
        low = rng.uniform(0.0, 6.0)
        nxt = rng.uniform(12.0, 25.0)
        tau = np.arange(int(np.ceil(period_s)), dtype=np.float64)
        tau = tau[tau < period_s]
        down = tau < period_s / 2
        v = np.where(down, low + (top - low) * (1 + np.cos(2 * np.pi * tau / period_s)) / 2,
                     low + (nxt - low) * (1 + np.cos(2 * np.pi * tau / period_s)) / 2)
        pieces.append(v)
        top = nxt
    v = np.concatenate(pieces + [[top]])
    return np.arange(v.size, dtype=np.float64), v


def write_csv(path, t, v):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    np.savetxt(path, np.column_stack([t, v]), delimiter=",", header="time_s,speed_mps", comments="", fmt="%.17g")
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=1, help="the trace's seed (default 1)")
    ap.add_argument("--waves", type=int, default=12, help="number of waves (default 12)")
    ap.add_argument("-o", "--output", required=True, help="CSV file to write (time_s,speed_mps)")
    args = ap.parse_args()
    t, v = stop_and_go(args.seed, args.waves)
    print(write_csv(args.output, t, v))


if __name__ == "__main__":
    main()
