#!/usr/bin/python3
"""How vehicles leave the two lanes that end (the merge lane at 2300 m, the dropped lane at 4500 m), after the
warm-up, in a wavefuel run with trajectories or a SUMO run kept by sumo_corridor.py (README.md, "Why they differ").

wavefuel: a corridor.yaml run with `--set output.trajectories=true --set output.trajectory_interval_s=0.2`; a change
is a vehicle's lane differing between two consecutive frames (speed: the last frame in the old lane, position: the
first in the new one). Printed per lane end: changes, speed median / p10 / p90, share from standstill (< 0.5 m/s),
distance before the lane's end; for the dropped lane also the new follower's least acceleration in the 3 s after the
change (the braking the change imposed). Then, per band of x, each lane's mean speed and flow (sum of speeds over
the band's length, per frame), and the queue's tail: the first 100 m cell upstream of 4500 m whose mean speed is
below 10 m/s, per 300 s. Lanes are wavefuel's numbers (0 the merge lane, 1 the rightmost main lane, 3 the one that
ends at 4500 m).

SUMO: the directory of `sumo_corridor.py --keep DIR` (lanechanges.xml: changes from `mid_2` to `mid_1` and from
`merge_0` to `merge_1`, with SUMO's own speed, position and reason); the bands and the queue's tail when DIR also
holds fcd.xml (positions every second: sumo rerun in DIR with `--fcd-output fcd.xml --device.fcd.period 1`, the
command in README.md).
Usage: /usr/bin/python3 bench/lanes_sumo/lane_ends.py wavefuel RUN.h5 | sumo DIR"""
import os
import sys
import xml.etree.ElementTree as ET
from collections import Counter

import numpy as np

W0 = 600.0
DROP, MERGE_END = 4500.0, 2300.0
BANDS = ((1500, 2000), (2000, 2300), (3000, 3500), (3800, 4200), (4200, 4500), (4500, 4800))
OFF = {"up": 0.0, "merge": 2000.0, "mid": 2300.0, "down": 4500.0}  # SUMO edges: start x
LANE = {"up": (1, 2, 3), "merge": (0, 1, 2, 3), "mid": (1, 2, 3), "down": (1, 2)}  # SUMO lane index -> wavefuel's


def describe(name, v, dist, extra=""):
    if not len(v):
        print(f"{name}: none")
        return
    p = lambda a, q: np.percentile(a, q)
    print(f"{name}: {len(v)} changes; speed median {np.median(v):.1f} m/s (p10 {p(v, 10):.1f}, p90 {p(v, 90):.1f}), "
          f"{100 * np.mean(v < 0.5):.0f} % from standstill; distance before the end median {np.median(dist):.0f} m "
          f"(p10 {p(dist, 10):.0f}, p90 {p(dist, 90):.0f}), {100 * np.mean(dist <= 300):.0f} % within 300 m, "
          f"{100 * np.mean(dist <= 50):.0f} % within 50 m{extra}")


def bands(t, x, lane, v):
    w = t >= W0
    frames = len(np.unique(t[w]))
    for lo, hi in BANDS:
        m = w & (x >= lo) & (x < hi)
        parts = [f"lane {k} {v[m & (lane == k)].mean():4.1f} m/s {v[m & (lane == k)].sum() / (hi - lo) / frames * 3600:5.0f}"
                 f" veh/h" for k in range(4) if (m & (lane == k)).any()]
        print(f"  x {lo}-{hi} m: " + "; ".join(parts))
    edges = np.arange(0, DROP + 1, 100)
    tails = []
    for t0 in range(0, int(t.max()) + 1, 300):
        m = (t >= t0) & (t < t0 + 300) & (x < DROP)
        i = np.digitize(x[m], edges) - 1
        n = np.bincount(i, None, len(edges))
        s = np.bincount(i, v[m], len(edges)) / np.maximum(n, 1)
        slow = np.nonzero((s < 10) & (n > 0))[0]
        tails.append(f"{t0}: {edges[slow.min()]:.0f}" if len(slow) else f"{t0}: -")
    print("  queue tail (m) per 300 s from t: " + ", ".join(tails))


def wavefuel(path):
    import h5py
    with h5py.File(path) as f:
        T = {k: f["trajectories"][k][:] for k in ("t", "serial", "x", "v", "a", "lane")}
    o = np.lexsort((T["t"], T["serial"]))
    T = {k: v[o] for k, v in T.items()}
    s, lane, t = T["serial"], T["lane"], T["t"]
    same = s[1:] == s[:-1]
    for frm, to, end, name in ((3, 2, DROP, "dropped lane 3 -> 2"), (0, 1, MERGE_END, "merge lane 0 -> 1")):
        i = np.nonzero(same & (lane[:-1] == frm) & (lane[1:] == to) & (t[1:] >= W0))[0]
        extra = ""
        if frm == 3 and len(i):
            # the new follower: the vehicle right behind in lane `to` at the first frame in it
            key = np.round(t * 10).astype(np.int64) * 8 + lane.astype(np.int64)
            o2 = np.lexsort((T["x"], key))
            k2, x2, s2 = key[o2], T["x"][o2], s[o2]
            amin = []
            for j in i + 1:
                kk = key[j]
                lo, hi = np.searchsorted(k2, kk), np.searchsorted(k2, kk, "right")
                pos = np.searchsorted(x2[lo:hi], T["x"][j])
                if pos == 0:
                    continue
                f = s2[lo + pos - 1]
                a0 = np.searchsorted(s, f)
                a1 = np.searchsorted(s, f, "right")
                m = (t[a0:a1] >= t[j]) & (t[a0:a1] <= t[j] + 3)
                if m.any():
                    amin.append(T["a"][a0:a1][m].min())
            amin = np.array(amin)
            extra = (f"; new follower's least acceleration in 3 s: median {np.median(amin):.2f} m/s², "
                     f"{100 * np.mean(amin < -1.5):.0f} % below -1.5, {100 * np.mean(amin < -3):.0f} % below -3")
        describe(name, T["v"][i], end - T["x"][i + 1], extra)
    bands(t, T["x"], lane, T["v"])


def sumo(d):
    rows = []
    for _, el in ET.iterparse(os.path.join(d, "lanechanges.xml")):
        if el.tag == "change":
            if float(el.get("time")) >= W0:
                rows.append(dict(el.attrib))
            el.clear()
    for frm, to, end, name in (("mid_2", "mid_1", 2200.0, "dropped lane mid_2 -> mid_1"),
                               ("merge_0", "merge_1", 300.0, "merge lane merge_0 -> merge_1")):
        r = [x for x in rows if x["from"] == frm and x["to"] == to]
        describe(name, np.array([float(x["speed"]) for x in r]), end - np.array([float(x["pos"]) for x in r]),
                 "; reasons " + ", ".join(f"{k} {n}" for k, n in Counter(x["reason"] for x in r).most_common(3)))
    print("  changes by lanes: " + ", ".join(f"{f}->{t} {n}" for (f, t), n in
                                             Counter((x["from"], x["to"]) for x in rows).most_common(10)))
    fcd = os.path.join(d, "fcd.xml")
    if not os.path.exists(fcd):
        return
    out, t = [], None
    for ev, el in ET.iterparse(fcd, events=("start", "end")):
        if ev == "start" and el.tag == "timestep":
            t = float(el.get("time"))
        elif ev == "end" and el.tag == "vehicle":
            e, k = el.get("lane").rsplit("_", 1)
            out.append((t, OFF[e] + float(el.get("pos")), LANE[e][int(k)], float(el.get("speed"))))
            el.clear()
    a = np.array(out)
    bands(a[:, 0], a[:, 1], a[:, 2], a[:, 3])


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] not in ("wavefuel", "sumo"):
        sys.exit(__doc__)
    (wavefuel if sys.argv[1] == "wavefuel" else sumo)(sys.argv[2])
