#!/usr/bin/python3
"""Figures of a wavefuel corridor result (road.type: corridor): the time-space diagram of speed (from the
trajectories when the result has them, else from the Edie speed field), the Edie fuel field (g per km of road per
hour), and each class's fuel per vehicle-km along the road with the grade profile. Layout: docs/corridors.md.
Usage:
    /usr/bin/python3 tools/plot_corridor.py RESULT.h5 [-o FIGURE.png] [--edie] [--max-points N]
"""
import argparse
import sys

import h5py
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def text(d):
    v = d[()]
    return v.decode() if isinstance(v, bytes) else str(v)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("result")
    ap.add_argument("-o", "--output", help="figure file (default: RESULT with .png)")
    ap.add_argument("--edie", action="store_true", help="speed from the Edie field even when trajectories exist")
    ap.add_argument("--max-points", type=int, default=400000, help="trajectory points drawn (subsampled)")
    args = ap.parse_args()
    out = args.output or args.result.rsplit(".h5", 1)[0] + ".png"
    with h5py.File(args.result, "r") as f:
        if "edie" not in f or "road" not in f:
            sys.exit(f"{args.result}: not a corridor result (no /edie and /road)")
        L = float(f["meta/road_length"][()])
        te, xe = f["edie/t_edges"][:], f["edie/x_edges"][:]
        speed, fuel = f["edie/speed"][:], f["edie/fuel"][:]
        xc, grade = f["edie/x"][:], f["edie/grade"][:]
        cpk = f["edie/class_fuel_per_km"][:]
        names = [s.decode() if isinstance(s, bytes) else s for s in f["classes/name"][:]]
        traj = None
        if "trajectories" in f and not args.edie:
            n = f["trajectories/t"].shape[0]
            step = max(1, n // args.max_points)
            traj = (f["trajectories/t"][::step], f["trajectories/x"][::step], f["trajectories/v"][::step])
        zones = []
        if "road/zone_type" in f:
            for k, z in enumerate(f["road/zone_type"][:]):
                z = z.decode() if isinstance(z, bytes) else z
                zones.append((z, f["road/zone_from"][k], f["road/zone_to"][k]))
        title = text(f["meta/scenario_path"])

    vmax = max(1.0, np.nanmax(speed) if np.isfinite(speed).any() else 1.0)
    fig, axes = plt.subplots(3, 1, figsize=(10, 11), gridspec_kw={"height_ratios": [3, 3, 2]})
    ax1, ax2, ax3 = axes
    if traj is not None:
        sc = ax1.scatter(traj[0], traj[1], c=traj[2], s=0.3, cmap="RdYlGn", vmin=0, vmax=vmax, rasterized=True)
        ax1.set_title(f"{title}: trajectories coloured by speed")
    else:
        sc = ax1.pcolormesh(te, xe, speed.T, cmap="RdYlGn", vmin=0, vmax=vmax, shading="flat", rasterized=True)
        ax1.set_title(f"{title}: Edie speed v = q / k")
    fig.colorbar(sc, ax=ax1, label="speed (m/s)")
    pm = ax2.pcolormesh(te, xe, fuel.T, cmap="magma_r", shading="flat", rasterized=True)
    fig.colorbar(pm, ax=ax2, label="fuel (g per km of road per hour)")
    ax2.set_title("Edie fuel field")
    for ax in (ax1, ax2):
        ax.set_xlabel("time (s)")
        ax.set_ylabel("position x (m)")
        ax.set_ylim(0, L)
        for kind, a, b in zones:
            ax.axhspan(a, b, color="tab:blue" if kind == "speed_limit" else "tab:purple", alpha=0.12, lw=0)
    for c in range(cpk.shape[0]):
        if np.isfinite(cpk[c]).any():
            ax3.plot(xc, cpk[c], lw=1.2, label=names[c])
    ax3.set_yscale("log")
    ax3.set_xlabel("position x (m)")
    ax3.set_ylabel("fuel per vehicle-km (g/km)")
    ax3.set_title("fuel per vehicle-km by class along the road (statistics window)")
    ax3.set_xlim(0, L)
    ax3.legend(fontsize=7, ncol=3, loc="upper left")
    axg = ax3.twinx()
    axg.plot(xc, 100 * np.tan(grade), "k--", lw=0.8)
    axg.set_ylabel("grade (%), dashed")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
