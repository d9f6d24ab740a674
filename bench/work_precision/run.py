#!/usr/bin/python3
"""Work-precision study (issue 5): error in total fleet fuel and in final positions against a tight CVODES
reference, versus wall time, for ballistic, Euler and RK4 at several dt and CVODES / ARKODE at several
tolerances. Writes bench/work_precision/results.csv, prints a Markdown table, draws work_precision.png.
Usage: /usr/bin/python3 bench/work_precision/run.py [--bin bin/wavefuel] [--threads 1]"""
import argparse, csv, os, subprocess, tempfile

import h5py
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SCEN = os.path.join(HERE, "ring.yaml")


def run(binary, threads, tmp, name, sets):
    out = os.path.join(tmp, name + ".h5")
    cmd = [binary, "run", SCEN, "-q", "--force", "-o", out, "--threads", str(threads)]
    for s in sets:
        cmd += ["--set", s]
    subprocess.run(cmd, check=True)
    with h5py.File(out) as f:
        r = dict(fuel=f["summary/fuel"][()], x=f["vehicles/final_x"][:], wall=f["meta/wall_time_s"][()])
        r["rhs"] = int(f["solver/rhs_evals"][()]) if "solver" in f else None
    os.unlink(out)
    return r


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default="bin/wavefuel")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    tight = ["time.integrator=cvode", "solver.rtol=1e-11", "solver.atol_x_m=1e-10", "solver.atol_v_mps=1e-10",
             "solver.atol_fuel_g=1e-10", "solver.fuel_error_control=true", "time.dt_s=0.1"]
    configs = []
    for dt in ["0.4", "0.2", "0.1", "0.05", "0.025"]:
        configs.append(("ballistic", f"dt={dt}", ["time.integrator=ballistic", f"time.dt_s={dt}"]))
        configs.append(("euler", f"dt={dt}", ["time.integrator=euler", f"time.dt_s={dt}"]))
    for sub in ["1", "2", "4"]:
        h = 0.4 / int(sub)
        configs.append(("rk4", f"h={h:g}", ["time.integrator=rk4", "time.dt_s=0.4", f"solver.rk4_substeps={sub}"]))
    for tol in ["1e-3", "1e-4", "1e-5", "1e-6", "1e-7", "1e-8"]:
        tl = [f"solver.rtol={tol}", f"solver.atol_x_m={tol}", f"solver.atol_v_mps={tol}", "time.dt_s=0.1"]
        configs.append(("cvode", f"tol={tol}", ["time.integrator=cvode"] + tl))
        configs.append(("arkode", f"tol={tol}", ["time.integrator=arkode"] + tl))
    with tempfile.TemporaryDirectory() as tmp:
        ref = run(args.bin, args.threads, tmp, "ref", tight)
        rows = []
        for method, label, sets in configs:
            r = run(args.bin, args.threads, tmp, "run", sets)
            rows.append(dict(method=method, setting=label, wall_s=r["wall"],
                             fuel_rel_err=abs(r["fuel"] - ref["fuel"]) / ref["fuel"],
                             x_max_err_m=float(np.max(np.abs(r["x"] - ref["x"]))), rhs_evals=r["rhs"] or ""))
    with open(os.path.join(HERE, "results.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"reference: CVODES rtol 1e-11, fleet fuel {ref['fuel']:.6f} g, wall {ref['wall']:.2f} s, "
          f"{args.threads} thread(s)\n")
    print("| method | setting | wall (s) | fuel rel. error | max position error (m) | RHS evals |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['method']} | {r['setting']} | {r['wall_s']:.3f} | {r['fuel_rel_err']:.2e} | "
              f"{r['x_max_err_m']:.2e} | {r['rhs_evals']} |")
    ok = [r for r in rows if r["fuel_rel_err"] <= 1e-3]
    if ok:
        best = min(ok, key=lambda r: r["wall_s"])
        print(f"\ncheapest run within 0.1 % of the reference fuel: {best['method']} {best['setting']} "
              f"({best['wall_s']:.3f} s, error {best['fuel_rel_err']:.2e})")
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.5))
    for m, mk in [("ballistic", "o-"), ("euler", "s-"), ("rk4", "^-"), ("cvode", "D-"), ("arkode", "v-")]:
        rr = [r for r in rows if r["method"] == m]
        ax[0].loglog([r["wall_s"] for r in rr], [max(r["fuel_rel_err"], 1e-16) for r in rr], mk, label=m)
        ax[1].loglog([r["wall_s"] for r in rr], [max(r["x_max_err_m"], 1e-16) for r in rr], mk, label=m)
    ax[0].axhline(1e-3, color="0.5", ls=":", label="0.1 %")
    ax[0].set_xlabel("wall time (s)"); ax[0].set_ylabel("relative error of fleet fuel")
    ax[1].set_xlabel("wall time (s)"); ax[1].set_ylabel("max final position error (m)")
    for a in ax:
        a.legend(fontsize=8); a.grid(True, which="both", alpha=0.3)
    fig.suptitle("work-precision: 2200 vehicles, 300 s, stop-and-go waves")
    fig.tight_layout()
    fig.savefig(os.path.join(HERE, "work_precision.png"), dpi=100)


if __name__ == "__main__":
    main()
