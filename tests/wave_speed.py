#!/usr/bin/python3
"""Speed of a stop-and-go wave on a ring, measured from a wavefuel result's trajectories (/trajectories/x, v,
output.trajectories: true), after the warm-up. Two independent methods, in the ground frame (negative: the wave
moves backwards, against the traffic):

  xcorr    the speed field v(x, t) on a 1 m grid of the ring (each vehicle's speed interpolated periodically
           between vehicles); for a lag tau, the circular cross-correlation of v(., t) and v(., t + tau),
           summed over t, peaks at the shift the field moved by: c = shift / tau.
  slowest  the position of the slowest vehicle in every frame, unwrapped around the ring; c = the slope of
           its least-squares line over time.

Also: the mean number of vehicles slower than 2 m/s in a frame, the mean speed, and the speed of the free-flow
part (the vehicles' 90th-percentile speed). Usage:
    /usr/bin/python3 tests/wave_speed.py RESULT.h5 [--lag-s 5]
prints "key value" lines (speeds in m/s; wave speeds also in km/h).
"""
import argparse
import sys

import h5py
import numpy as np


def load(path):
    with h5py.File(path, "r") as f:
        if "trajectories" not in f:
            sys.exit(f"{path}: no /trajectories (run with --set output.trajectories=true)")
        L = float(f["meta/road_length"][()])
        warm = float(f["meta/warmup"][()])
        t = f["trajectories/t"][:]
        x = f["trajectories/x"][:]
        v = f["trajectories/v"][:]
    keep = t >= warm
    return L, t[keep], x[keep] % L, v[keep]


def speed_field(L, x, v, n_cells):
    """v on n_cells points of [0, L): linear between consecutive vehicles around the ring."""
    grid = (np.arange(n_cells) + 0.5) * (L / n_cells)
    field = np.empty((x.shape[0], n_cells))
    for k in range(x.shape[0]):
        order = np.argsort(x[k])
        xs, vs = x[k][order], v[k][order]
        # Periodic: the last vehicle before the first, one lap back, and the first after the last.
        xs = np.concatenate(([xs[-1] - L], xs, [xs[0] + L]))
        vs = np.concatenate(([vs[-1]], vs, [vs[0]]))
        field[k] = np.interp(grid, xs, vs)
    return field


def xcorr_speed(L, t, x, v, lag_s):
    n_cells = int(round(L))
    dx = L / n_cells
    dt = float(np.median(np.diff(t)))
    lag = int(round(lag_s / dt))
    if lag < 1 or lag >= len(t):
        sys.exit(f"lag {lag_s} s does not fit the frames (interval {dt} s, {len(t)} frames)")
    field = speed_field(L, x, v, n_cells)
    field -= field.mean(axis=1, keepdims=True)
    spec = np.fft.rfft(field, axis=1)
    # corr[s] = sum_t sum_x u(x, t) u(x - s, t + lag): the field at t + lag is the field at t moved by s.
    cross = (np.conj(spec[:-lag]) * spec[lag:]).sum(axis=0)
    corr = np.fft.irfft(cross, n=n_cells)
    s = int(np.argmax(corr))
    # Parabolic refinement around the peak (periodic neighbours).
    ym, y0, yp = corr[(s - 1) % n_cells], corr[s], corr[(s + 1) % n_cells]
    den = ym - 2 * y0 + yp
    frac = 0.5 * (ym - yp) / den if den != 0 else 0.0
    shift = (s + frac) * dx
    if shift > L / 2:
        shift -= L
    return shift / (lag * dt)


def slowest_track(L, t, x, v):
    pos = x[np.arange(len(t)), np.argmin(v, axis=1)]
    step = np.diff(pos)
    step = (step + L / 2) % L - L / 2  # shortest way around the ring
    path = np.concatenate(([pos[0]], pos[0] + np.cumsum(step)))
    return float(np.polyfit(t, path, 1)[0])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("result")
    ap.add_argument("--lag-s", type=float, default=5.0, help="lag of the cross-correlation (s)")
    args = ap.parse_args()
    L, t, x, v = load(args.result)
    c1 = xcorr_speed(L, t, x, v, args.lag_s)
    c2 = slowest_track(L, t, x, v)
    print(f"wave_speed_xcorr_mps {c1:.4f}")
    print(f"wave_speed_xcorr_kmh {c1 * 3.6:.3f}")
    print(f"wave_speed_slowest_mps {c2:.4f}")
    print(f"wave_speed_slowest_kmh {c2 * 3.6:.3f}")
    print(f"slow_vehicles_mean {np.mean(np.sum(v < 2.0, axis=1)):.3f}")
    print(f"vehicles {x.shape[1]}")
    print(f"mean_speed_mps {v.mean():.4f}")
    print(f"free_speed_p90_mps {np.percentile(v, 90):.4f}")
    print(f"frames {len(t)}")


if __name__ == "__main__":
    main()
