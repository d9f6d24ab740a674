#!/usr/bin/python3
"""Time-space diagram coloured by speed, and the fleet and per-class fuel-rate time series, from a wavefuel
result file (needs /trajectories: set output.trajectories: true). Usage:
    /usr/bin/python3 tools/plot_timespace.py RESULT.h5 [-o FIGURE.png] [--max-vehicles N]
"""
import argparse
import sys

import h5py
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("result")
    ap.add_argument("-o", "--output", help="figure file (default: RESULT with .png)")
    ap.add_argument("--max-vehicles", type=int, default=400, help="vehicles drawn in the time-space diagram")
    args = ap.parse_args()
    out = args.output or args.result.rsplit(".h5", 1)[0] + ".png"
    with h5py.File(args.result, "r") as f:
        if "trajectories" not in f:
            sys.exit(f"{args.result}: no /trajectories (run with --set output.trajectories=true)")
        L = float(f["meta/road_length"][()])
        t = f["trajectories/t"][:]
        n = f["trajectories/x"].shape[1]
        step = max(1, n // args.max_vehicles)
        x = f["trajectories/x"][:, ::step] % L
        v = f["trajectories/v"][:, ::step]
        ts_t = f["timeseries/t"][:]
        fuel = f["timeseries/fuel_rate"][:]
        cls = f["timeseries/class_fuel_rate"][:]
        names = [s.decode() if isinstance(s, bytes) else s for s in f["classes/name"][:]]
        warm = float(f["meta/warmup"][()])
        title = f["meta/scenario_path"][()]
        title = title.decode() if isinstance(title, bytes) else title

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(10, 8), gridspec_kw={"height_ratios": [3, 1]}, sharex=True)
    tt = np.repeat(t[:, None], x.shape[1], axis=1)
    # Break lines where a vehicle wraps around the ring so no segment crosses the plot.
    sc = ax1.scatter(tt.ravel(), x.ravel(), c=v.ravel(), s=0.3, cmap="RdYlGn", vmin=0, vmax=max(1.0, v.max()),
                     rasterized=True)
    fig.colorbar(sc, ax=ax1, label="speed (m/s)")
    ax1.set_ylabel("position on the ring (m)")
    ax1.set_title(f"{title}: time-space diagram")
    ax2.plot(ts_t, fuel, "k", lw=1.2, label="fleet")
    if cls.ndim == 2 and cls.shape[1] > 1:
        for c in range(cls.shape[1]):
            ax2.plot(ts_t, cls[:, c], lw=0.8, label=names[c])
    ax2.axvspan(0, warm, color="0.9", label="warm-up")
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("fuel rate (g/s)")
    ax2.legend(fontsize=7, ncol=4)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
