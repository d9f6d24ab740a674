#!/usr/bin/python3
"""Figures of a wavefuel corridor result (road.type: corridor): the time-space diagram of speed (from the
trajectories when the result has them, else from the Edie speed field), the Edie fuel field (g per km of road per
hour), and each class's fuel per vehicle-km along the road with the grade profile. Layout: docs/corridors.md.
Usage:
    /usr/bin/python3 tools/plot_corridor.py RESULT.h5 [-o FIGURE.png] [--edie] [--max-points N] [--vmax M_PER_S]
Automated vehicles (driver groups with a controller) are drawn as black lines when the result has trajectories.
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import wfplot  # noqa: E402

import numpy as np  # noqa: E402

MAX_AV_LINES = 200   # automated vehicles drawn as lines (evenly chosen among them beyond this)


def automated_paths(f, rows):
    """([(t, x)] per automated vehicle, sorted in time; the automated models): the trajectory points of the serials
    whose trip is in an automated driver group (at most MAX_AV_LINES of them)."""
    auto = wfplot.automated_groups(f)
    if not auto or "trips/serial" not in f:
        return [], []
    trip_rows = int(f["meta/trip_rows"][()]) if "meta/trip_rows" in f else f["trips/serial"].shape[0]
    serial, group = f["trips/serial"][:trip_rows], f["trips/group_id"][:trip_rows]
    av = serial[np.isin(group, list(auto))]
    models = sorted({auto[int(g)] for g in group if int(g) in auto})
    if len(av) > MAX_AV_LINES:
        av = av[:: -(-len(av) // MAX_AV_LINES)]
    ps = f["trajectories/serial"][:rows]
    pick = np.isin(ps, av)
    if not pick.any():
        return [], models
    t, x, ps = f["trajectories/t"][:rows][pick], f["trajectories/x"][:rows][pick], ps[pick]
    order = np.lexsort((t, ps))
    t, x, ps = t[order], x[order], ps[order]
    cut = np.flatnonzero(np.diff(ps)) + 1
    return list(zip(np.split(t, cut), np.split(x, cut))), models


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("result")
    ap.add_argument("-o", "--output", help="figure file (default: RESULT with .png)")
    ap.add_argument("--edie", action="store_true", help="speed from the Edie field even when trajectories exist")
    ap.add_argument("--max-points", type=int, default=400000, help="trajectory points drawn (subsampled)")
    ap.add_argument("--vmax", type=wfplot.positive, metavar="M_PER_S",
                    help="top of the speed colour scale in m/s (default: the fastest Edie speed), so that several "
                         "figures share one scale")
    args = ap.parse_args()
    out = args.output or args.result.rsplit(".h5", 1)[0] + ".png"
    with wfplot.open_file(args.result, ("corridor",), sys.argv[0]) as f:
        L = float(f["meta/road_length"][()])
        te, xe = f["edie/t_edges"][:], f["edie/x_edges"][:]
        speed, fuel = f["edie/speed"][:], f["edie/fuel"][:]
        xc, grade = f["edie/x"][:], f["edie/grade"][:]
        cpk = f["edie/class_fuel_per_km"][:]
        names = [wfplot.text(s) for s in f["classes/name"][()]]
        traj, avs, av_models = None, [], []
        if "trajectories" in f:
            rows = int(f["meta/trajectory_rows"][()])
            if not args.edie and rows:
                step = max(1, rows // args.max_points)
                traj = (f["trajectories/t"][:rows:step], f["trajectories/x"][:rows:step],
                        f["trajectories/v"][:rows:step])
            avs, av_models = automated_paths(f, rows)
        zones = []
        if "road/zone_type" in f:
            for k, z in enumerate(f["road/zone_type"][()]):
                zones.append((wfplot.text(z), f["road/zone_from"][k], f["road/zone_to"][k]))
        title = wfplot.text(f["meta/scenario_path"])

    import matplotlib   # here, after the file checks: a wrong file is refused without the cost of importing it
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    vmax = args.vmax or max(1.0, np.nanmax(speed) if np.isfinite(speed).any() else 1.0)
    fig = plt.figure(figsize=(10, 12))
    # A narrow column for the colour bars, so the two time axes (and the position axis below) have one width.
    gs = fig.add_gridspec(3, 2, width_ratios=[40, 1], height_ratios=[3, 3, 2], hspace=0.3, wspace=0.03)
    ax1 = fig.add_subplot(gs[0, 0])
    ax2 = fig.add_subplot(gs[1, 0], sharex=ax1)
    ax3 = fig.add_subplot(gs[2, 0])
    if traj is not None:
        sc = ax1.scatter(traj[0], traj[1], c=traj[2], s=0.3, cmap="RdYlGn", vmin=0, vmax=vmax, rasterized=True)
        ax1.set_title(f"{title}: trajectories coloured by speed", loc="left", fontsize=10)
    else:
        sc = ax1.pcolormesh(te, xe, speed.T, cmap="RdYlGn", vmin=0, vmax=vmax, shading="flat", rasterized=True)
        ax1.set_title(f"{title}: Edie speed v = q / k", loc="left", fontsize=10)
    fig.colorbar(sc, cax=fig.add_subplot(gs[0, 1]), label="speed (m/s)",
                 extend="max" if np.nanmax(speed, initial=0) > vmax else "neither")
    for k, (t, x) in enumerate(avs):
        ax1.plot(t, x, color="k", lw=0.7, label=f"automated vehicles ({', '.join(av_models)})" if k == 0 else None)
    if avs:
        ax1.legend(loc="lower right", bbox_to_anchor=(1, 1.0), fontsize=8, frameon=False)
    pm = ax2.pcolormesh(te, xe, fuel.T, cmap="magma_r", shading="flat", rasterized=True)
    fig.colorbar(pm, cax=fig.add_subplot(gs[1, 1]), label="fuel (g per km of road per hour)")
    ax2.set_title("Edie fuel field", loc="left", fontsize=10)
    for ax in (ax1, ax2):
        ax.set_xlabel("time (s)")
        ax.set_ylabel("position x (m)")
        ax.set_xlim(te[0], te[-1])
        ax.set_ylim(0, L)
        for kind, a, b in zones:
            ax.axhspan(a, b, color="tab:blue" if kind == "speed_limit" else "tab:purple", alpha=0.12, lw=0)
    for c in range(cpk.shape[0]):
        if np.isfinite(cpk[c]).any():
            ax3.plot(xc, cpk[c], lw=1.2, label=names[c])
    ax3.set_yscale("log")
    ax3.set_xlabel("position x (m)")
    ax3.set_ylabel("fuel per vehicle-km (g/km)")
    ax3.set_title("fuel per vehicle-km by class along the road (statistics window)", loc="left", fontsize=10)
    ax3.set_xlim(0, L)
    axg = ax3.twinx()
    (g,) = axg.plot(xc, 100 * np.tan(grade), "k--", lw=0.8, label="grade (%)")
    axg.set_ylabel("grade (%)")
    # Below the panel, clear of the curves.
    h, lab = ax3.get_legend_handles_labels()
    ax3.legend(h + [g], lab + ["grade (%), right axis"], loc="upper center", bbox_to_anchor=(0.5, -0.2),
               fontsize=8, ncol=4, frameon=False)
    fig.savefig(out, dpi=110, bbox_inches="tight")
    print(out)


if __name__ == "__main__":
    main()
