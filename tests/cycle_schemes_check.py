#!/usr/bin/python3
"""Recompute `wavefuel cycle`'s release and spline schemes independently and compare the cycle fuel.

Written from the CIRCLES release's validation script (plot_semiprincipled_vs_simplified_model_on_drivecycles.m)
and its model files, with SciPy and NumPy only; it shares no code with wavefuel:
  - the trace: SciPy's CubicSpline(bc_type='not-a-knot') of the 1 Hz samples, set to 0 where it is below 0 and
    between two samples that are both 0 (what the release's 10 Hz files hold; docs/cycles.md);
  - release: that trace at 10 Hz, the script's D_a = (D_v([2:end,end]) - D_v([1,1:end-1])) ./ (same for D_t),
    the fuel rate with projection (the script's flag_project = true), summed with numpy.trapz;
  - spline: the trace at 100 Hz with the spline's own derivative (0 where the trace is 0), numpy.trapz;
  - the fuel rate: the release's simplified-model formula, coefficients read from the class files (PyYAML).
Cases: every shipped class on each cycle of its duty at every protocol grade (release scheme, from one
`wavefuel cycle --protocol --scheme release -o` file), each class and cycle at +0.01 rad (spline scheme, single
runs), and a synthetic trace with uneven steps and non-zero end speeds, where not-a-knot and natural end conditions
differ. Tolerance: 1e-9 relative on every fuel total (the two sides differ only by rounding: the linear solves,
the order of the sums). Negative controls: forward differences in place of the central ones, and a natural spline
in place of not-a-knot, must each miss by more than 1000 times the tolerance, or the check could not see them.
Usage: cycle_schemes_check.py BIN DATA_DIR VEHICLES_DIR TMPDIR. Prints PASS/FAIL lines; exit status 1 on a FAIL.
"""
import glob
import os
import subprocess
import sys

import h5py
import numpy as np
import yaml
from scipy.interpolate import CubicSpline

REL_TOL = 1e-9
LIGHT = ["udds", "hwfet", "us06", "wltc3"]
HEAVY = ["hhddt_cruise", "hhddt_transient", "hhddt_h65"]


def load_class(path):
    doc = yaml.safe_load(open(path))
    return doc["duty"], {k: float(v) for k, v in doc["energy"].items()}


def fuel_rate(p, heavy, v, a, th, project):
    """The release's fuel_model_*_simplified.m, vectorised (heavy duty: lower bound h0 + h1 v, no fuel cut)."""
    ma = np.minimum(p["b1"], p["b2"] / np.maximum(v, 1e-12) - p["b3"] * np.maximum(v, 0) ** 2) - np.minimum(
        p["b4"], p["b5"] + p["b6"] * np.maximum(v, 0)) * th
    if project:
        a = np.minimum(a, ma)
    v = np.maximum(v, 0)
    aplus = np.maximum(a, -(p["p0"] + p["p1"] * v + p["p2"] * v ** 2) / (2 * (p["q0"] + p["q1"] * np.maximum(v, 1e-12))))
    f = (p["c0"] + p["c1"] * v + p["c2"] * v ** 2 + p["c3"] * v ** 3 + p["p0"] * a + p["p1"] * a * v
         + p["p2"] * a * v ** 2 + p["q0"] * aplus ** 2 + p["q1"] * aplus ** 2 * v + p["z0"] * th + p["z1"] * th * v
         + p["z2"] * th * v ** 2)
    if heavy:
        f = np.maximum(f, p["h0"] + p["h1"] * v)
    else:
        f = np.maximum(f, (v <= p["v_c"]) * p["beta"])
        a_brake = p["a0"] + p["a1"] * v + p["a2"] * th + p["a3"] * v ** 2 + p["a4"] * v * th
        f = np.where((v > p["v_c"]) & (a <= a_brake), 0.0, f)
    return np.where((v < 0.1) & (np.abs(a) < 0.01), p["f_idle"], f)


def trace(t, v, rate_hz, bc="not-a-knot"):
    """Times t0 + k / rate (and the end when the duration is not a whole number of steps), speed and derivative."""
    dur = t[-1] - t[0]
    k_max = int(np.floor(dur * rate_hz + 1e-9))
    tt = t[0] + np.arange(k_max + 1) / rate_hz
    if k_max / rate_hz < dur - 1e-9 * max(dur, 1.0):
        tt = np.append(tt, t[-1])
    tt[-1] = t[-1]
    s = CubicSpline(t, v, bc_type=bc)
    vv, dv = s(tt), s(tt, 1)
    k = np.clip(np.searchsorted(t, tt, side="right") - 1, 0, len(t) - 2)
    still = ((v[k] == 0) & (v[k + 1] == 0)) | (vv < 0)
    vv[still] = 0.0
    dv[still] = 0.0
    return tt, vv, dv


def script_accel(tt, vv):
    """D_a of the release's script: central differences, one-sided at both ends."""
    hi = np.r_[np.arange(1, len(vv)), len(vv) - 1]
    lo = np.r_[0, np.arange(0, len(vv) - 1)]
    return (vv[hi] - vv[lo]) / (tt[hi] - tt[lo])


def forward_accel(tt, vv):
    return np.append(np.diff(vv) / np.diff(tt), 0.0)


def cycle_fuel(cyc, p, heavy, th, scheme, project=True, variant=None):
    t, v = cyc
    if scheme == "release":
        tt, vv, _ = trace(t, v, 10.0, "natural" if variant == "natural" else "not-a-knot")
        a = forward_accel(tt, vv) if variant == "forward" else script_accel(tt, vv)
    else:
        tt, vv, a = trace(t, v, 100.0)
    return np.trapz(fuel_rate(p, heavy, vv, a, th, project), tt)


def read_cycle(path):
    d = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return d[:, 0], d[:, 1]


class Report:
    def __init__(self):
        self.failed = 0

    def check(self, name, ok, why):
        print(("PASS %s" % name) if ok else ("FAIL %s: %s" % (name, why)))
        self.failed += not ok


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError("%s: exit %d: %s" % (" ".join(cmd), r.returncode, r.stderr))
    return r.stdout


def single_fuel(binary, cls, cycle, grade, scheme, out, data):
    run([binary, "cycle", "--class", cls, "--scheme", scheme, "--project", "--grade", repr(grade), "--cycles", data,
         cycle, "-o", out, "--force"])
    with h5py.File(out, "r") as f:
        name = os.path.splitext(os.path.basename(cycle))[0]
        runs = f[os.path.splitext(os.path.basename(cls))[0]][name]
        return runs[list(runs)[0]]["circles_polynomial"]["fuel_g"][()]


def main():
    binary, data, vehicles, tmp = sys.argv[1:5]
    rep = Report()
    classes = {os.path.splitext(os.path.basename(p))[0]: load_class(p) for p in sorted(glob.glob(vehicles + "/*.yaml"))}
    cycles = {c: read_cycle("%s/cycles/%s.csv" % (data, c)) for c in LIGHT + HEAVY}

    # Release scheme: the whole protocol grid from one run.
    prot = os.path.join(tmp, "release.h5")
    run([binary, "cycle", "--protocol", "--scheme", "release", "--cycles", data, "-o", prot, "--force"])
    worst, worst_fwd, n = 0.0, 0.0, 0
    with h5py.File(prot, "r") as f:
        for cls, (duty, p) in classes.items():
            heavy = duty == "heavy"
            s = f[cls]["summary"]
            got = s["fuel_g_circles_polynomial"][:]
            for ci, cyc in enumerate(HEAVY if heavy else LIGHT):
                for gi, th in enumerate(s["grades_rad"][:]):
                    want = cycle_fuel(cycles[cyc], p, heavy, th, "release")
                    worst = max(worst, abs(got[ci, gi] - want) / want)
                    fwd = cycle_fuel(cycles[cyc], p, heavy, th, "release", variant="forward")
                    worst_fwd = max(worst_fwd, abs(got[ci, gi] - fwd) / fwd)
                    n += 1
    rep.check("release_scheme_protocol_grid", worst <= REL_TOL,
              "largest relative difference %.3g over %d runs (tolerance %g)" % (worst, n, REL_TOL))
    print("     release scheme: %d runs, largest relative difference %.2e" % (n, worst))
    rep.check("control_forward_differences_detected", worst_fwd > 1e3 * REL_TOL,
              "forward differences come within %.3g of wavefuel" % worst_fwd)

    # Spline scheme: single runs at +0.01 rad.
    worst, n = 0.0, 0
    out = os.path.join(tmp, "spline.h5")
    for cls, (duty, p) in classes.items():
        heavy = duty == "heavy"
        for cyc in HEAVY if heavy else LIGHT:
            got = single_fuel(binary, "%s/%s.yaml" % (vehicles, cls), cyc, 0.01, "spline", out, data)
            want = cycle_fuel(cycles[cyc], p, heavy, 0.01, "spline")
            worst = max(worst, abs(got - want) / want)
            n += 1
    os.remove(out)
    rep.check("spline_scheme_each_cycle", worst <= REL_TOL,
              "largest relative difference %.3g over %d runs (tolerance %g)" % (worst, n, REL_TOL))
    print("     spline scheme: %d runs, largest relative difference %.2e" % (n, worst))

    # A synthetic trace: uneven steps, moving at both ends, a duration that is not a whole number of 0.1 s steps.
    t = np.array([0.0, 0.7, 1.9, 3.0, 4.4, 5.0, 6.3, 8.05])
    v = np.array([3.0, 4.1, 6.0, 6.2, 5.1, 2.0, 0.4, 1.5])
    path = os.path.join(tmp, "uneven.csv")
    with open(path, "w") as fh:
        fh.write("time_s,speed_mps\n" + "".join("%r,%r\n" % (a, b) for a, b in zip(t, v)))
    duty, p = classes["midsize_suv"]
    for scheme in ("release", "spline"):
        got = single_fuel(binary, "%s/midsize_suv.yaml" % vehicles, path, 0.02, scheme, out, data)
        want = cycle_fuel((t, v), p, False, 0.02, scheme)
        rep.check("uneven_trace_" + scheme, abs(got - want) <= REL_TOL * want, "wavefuel %.17g, Python %.17g" % (got, want))
        if scheme == "release":
            nat = cycle_fuel((t, v), p, False, 0.02, scheme, variant="natural")
            rep.check("control_natural_spline_detected", abs(got - nat) > 1e3 * REL_TOL * nat,
                      "a natural spline comes within %.3g of wavefuel" % (abs(got - nat) / nat))
    os.remove(out)
    return 1 if rep.failed else 0


if __name__ == "__main__":
    sys.exit(main())
