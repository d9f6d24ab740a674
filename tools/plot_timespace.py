#!/usr/bin/python3
"""Time-space diagram coloured by speed, with the automated vehicles drawn as black lines, over the fleet and
per-class fuel-rate time series (one time axis), from a wavefuel ring result (needs /trajectories: set
output.trajectories: true). Usage:
    /usr/bin/python3 tools/plot_timespace.py RESULT.h5 [-o FIGURE.png] [--max-vehicles N] [--vmax M_PER_S]
A corridor result is drawn by tools/plot_corridor.py, a sweep table by tools/plot_sweep.py.
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import wfplot  # noqa: E402

import numpy as np  # noqa: E402


def columns(n, every, keep, limit):
    """Vehicle indices drawn: every `every`-th one plus those in keep (the automated ones, at most limit)."""
    keep = np.asarray(sorted(keep), dtype=int)
    if len(keep) > limit:
        keep = keep[:: -(-len(keep) // limit)]
    return np.union1d(np.arange(0, n, every), keep).astype(int), keep


def ring_line(t, x, L):
    """(t, x mod L) with a NaN where the vehicle wraps around the ring, so no segment crosses the plot."""
    xm = x % L
    wrap = np.flatnonzero(np.diff(xm) < -L / 2) + 1
    return np.insert(t, wrap, np.nan), np.insert(xm, wrap, np.nan)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("result")
    ap.add_argument("-o", "--output", help="figure file (default: RESULT with .png)")
    ap.add_argument("--max-vehicles", type=int, default=400, help="vehicles drawn in the time-space diagram")
    ap.add_argument("--vmax", type=wfplot.positive, metavar="M_PER_S",
                    help="top of the speed colour scale in m/s (default: the fastest speed drawn), so that several "
                         "figures share one scale")
    args = ap.parse_args()
    out = args.output or args.result.rsplit(".h5", 1)[0] + ".png"
    with wfplot.open_file(args.result, ("ring",), sys.argv[0]) as f:
        if "trajectories" not in f or int(f["meta/trajectory_rows"][()]) == 0:
            wfplot.fail(sys.argv[0], f"{args.result}: no trajectories (run with --set output.trajectories=true)")
        rows = int(f["meta/trajectory_rows"][()])
        L = float(f["meta/road_length"][()])
        t = f["trajectories/t"][:rows]
        n = f["trajectories/x"].shape[1]
        auto = wfplot.automated_groups(f)
        group = f["vehicles/group_id"][()]
        av = [i for i in range(n) if int(group[i]) in auto]
        cols, av = columns(n, max(1, n // args.max_vehicles), av, args.max_vehicles)
        x = f["trajectories/x"][:rows, cols]
        v = f["trajectories/v"][:rows, cols]
        ts_rows = int(f["meta/timeseries_rows"][()])
        ts_t = f["timeseries/t"][:ts_rows]
        fuel = f["timeseries/fuel_rate"][:ts_rows]
        cls = f["timeseries/class_fuel_rate"][:ts_rows]
        names = [wfplot.text(s) for s in f["classes/name"][()]]
        warm = float(f["meta/warmup"][()])
        title = wfplot.text(f["meta/scenario_path"])
        av_models = sorted({auto[int(group[i])] for i in av})

    import matplotlib   # here, after the file checks: a wrong file is refused without the cost of importing it
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig = plt.figure(figsize=(10, 8.5))
    # A narrow column for the colour bar beside both panels, so the two time axes have the same width.
    gs = fig.add_gridspec(2, 2, width_ratios=[40, 1], height_ratios=[3, 1.3], hspace=0.25, wspace=0.03)
    ax1 = fig.add_subplot(gs[0, 0])
    ax2 = fig.add_subplot(gs[1, 0], sharex=ax1)
    cax = fig.add_subplot(gs[0, 1])
    vmax = args.vmax or max(1.0, float(np.nanmax(v)))
    tt = np.repeat(t[:, None], x.shape[1], axis=1)
    sc = ax1.scatter(tt.ravel(), (x % L).ravel(), c=v.ravel(), s=0.3, cmap="RdYlGn", vmin=0, vmax=vmax,
                     rasterized=True)
    fig.colorbar(sc, cax=cax, label="speed (m/s)", extend="max" if np.nanmax(v) > vmax else "neither")
    for k, i in enumerate(av):
        j = int(np.searchsorted(cols, i))
        ax1.plot(*ring_line(t, x[:, j], L), color="k", lw=0.9,
                 label=f"automated vehicles ({', '.join(av_models)})" if k == 0 else None)
    ax1.set_ylabel("position on the ring (m)")
    ax1.set_xlim(t[0], t[-1])
    ax1.set_ylim(0, L)
    ax1.tick_params(labelbottom=False)
    fig.suptitle(f"{title}: time-space diagram and fuel rate")
    if len(av):
        ax1.legend(loc="lower left", bbox_to_anchor=(0, 1.0), fontsize=8, frameon=False)
    ax2.plot(ts_t, fuel, "k", lw=1.2, label="fleet")
    if cls.ndim == 2 and cls.shape[1] > 1:
        for c in range(cls.shape[1]):
            ax2.plot(ts_t, cls[:, c], lw=0.8, label=names[c])
    ax2.axvspan(0, warm, color="0.9", label="warm-up")
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("fuel rate (g/s)")
    # Above the panel, clear of the curves.
    ax2.legend(loc="lower left", bbox_to_anchor=(0, 1.0), fontsize=7, ncol=8, frameon=False)
    fig.savefig(out, dpi=110, bbox_inches="tight")
    print(out)


if __name__ == "__main__":
    main()
