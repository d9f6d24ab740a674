#!/usr/bin/python3
"""Plot a sweep's result table (`wavefuel sweep`, docs/sweeps.md): any metric against any axis, one line per value
of another axis, the mean over the runs that differ only by seed with their spread (s.d. error bars, or min-max).

  tools/plot_sweep.py TABLE.h5 --list
  tools/plot_sweep.py TABLE.h5 --metric l_per_100km --x av_count --lines controller [-o fig.png]
  tools/plot_sweep.py TABLE.h5 --metric class_fuel --class midsize_sedan --x av_count --where controller=acc

Every other axis must have one value among the rows plotted (fix it with --where AXIS=VALUE). Only rows with
status "ok" are used. The plotted means and spreads are also printed as a table.
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import wfplot  # noqa: E402

import numpy as np  # noqa: E402


def text(a):
    return np.array([x.decode() if isinstance(x, bytes) else str(x) for x in a])


def load(path):
    f = wfplot.open_file(path, ("sweep",), sys.argv[0])
    axes = {}
    for name, d in f["params"].items():
        v = d[()]
        keys = d.attrs.get("keys", "")
        keys = keys.decode() if isinstance(keys, bytes) else str(keys)
        axes[name] = (text(v) if v.dtype.kind in "OSU" else v, d.attrs.get("units", ""), keys)
    metrics = {n: (d[()], d.attrs["units"]) for n, d in f["metrics"].items()}
    class_metrics = {n: (d[()], d.attrs["units"]) for n, d in f["class_metrics"].items()}
    runs = {
        "status": text(f["runs/status"][()]),
        "seed": f["runs/seed"][()],
        "classes": [c.split(",") if c else [] for c in text(f["runs/classes"][()])],
    }
    return axes, metrics, class_metrics, runs


def units_text(u):
    u = u.decode() if isinstance(u, bytes) else str(u)
    return "" if u in ("", "1") else f" [{u}]"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("table")
    p.add_argument("--list", action="store_true", help="print the axes and metrics and exit")
    p.add_argument("--metric", help="a name in /metrics or /class_metrics")
    p.add_argument("--class", dest="cls", help="vehicle class, for a class_* metric")
    p.add_argument("--x", help="axis on the x axis (default: the first numeric axis)")
    p.add_argument("--lines", help="axis giving one line per value")
    p.add_argument("--where", action="append", default=[], metavar="AXIS=VALUE", help="keep rows with this value")
    p.add_argument("--spread", choices=("sd", "minmax", "none"), default="sd",
                   help="over seeds: sample s.d. error bars (default), min-max band, or none")
    p.add_argument("-o", "--output", help="image file (default: TABLE_METRIC_vs_X.png)")
    a = p.parse_args()

    axes, metrics, class_metrics, runs = load(a.table)
    if a.list:
        print("axes:")
        for n, (v, u, keys) in axes.items():
            vals = np.unique(v[~np.isnan(v)] if v.dtype.kind == "f" else v)
            shown = ", ".join(f"{x:g}" if v.dtype.kind == "f" else str(x) for x in vals)
            print(f"  {n:16s} {keys}{units_text(u)}: {shown}")
        print(f"seeds: {', '.join(str(s) for s in np.unique(runs['seed']))}")
        print("metrics:", ", ".join(f"{n}{units_text(u)}" for n, (_, u) in metrics.items()))
        print("class metrics (--class):", ", ".join(f"{n}{units_text(u)}" for n, (_, u) in class_metrics.items()))
        classes = sorted({c for cl in runs["classes"] for c in cl})
        print("classes:", ", ".join(classes))
        return
    if not a.metric:
        p.error("--metric is required (see --list)")

    ok = runs["status"] == "ok"
    if a.metric in metrics:
        y, yunits = metrics[a.metric]
        y = y.astype(float)
        label = a.metric
    elif a.metric in class_metrics:
        if not a.cls:
            wfplot.fail(sys.argv[0], f"{a.metric} is per class: give --class (see --list)")
        data, yunits = class_metrics[a.metric]
        y = np.full(len(ok), np.nan)
        for i, cl in enumerate(runs["classes"]):
            if a.cls in cl:
                y[i] = data[i, cl.index(a.cls)]
        ok &= ~np.isnan(y)
        label = f"{a.metric} ({a.cls})"
    else:
        wfplot.fail(sys.argv[0], f"no metric '{a.metric}'; known: {', '.join(list(metrics) + list(class_metrics))}")

    for w in a.where:
        name, _, value = w.partition("=")
        if name not in axes:
            wfplot.fail(sys.argv[0], f"--where {w}: no axis '{name}' (axes: {', '.join(axes)})")
        v = axes[name][0]
        if v.dtype.kind == "f":
            try:
                ok &= v == float(value)
            except ValueError:
                wfplot.fail(sys.argv[0], f"--where {w}: axis '{name}' is numeric, '{value}' is not a number")
        else:
            ok &= v == value
    x_name = a.x or next((n for n, (v, _, _) in axes.items() if v.dtype.kind == "f"), None)
    if x_name not in axes:
        wfplot.fail(sys.argv[0], f"--x: no axis '{x_name}' (axes: {', '.join(axes)})")
    if a.lines and a.lines not in axes:
        wfplot.fail(sys.argv[0], f"--lines: no axis '{a.lines}' (axes: {', '.join(axes)})")
    for n, (v, _, _) in axes.items():
        if n in (x_name, a.lines):
            continue
        vals = np.unique(v[ok])
        if len(vals) > 1:
            wfplot.fail(sys.argv[0], f"axis '{n}' has {len(vals)} values among the rows: fix one with --where "
                        f"{n}=VALUE, or plot it with --x/--lines")
    if not ok.any():
        wfplot.fail(sys.argv[0], "no row with status ok matches")

    xv = axes[x_name][0]
    lv = axes[a.lines][0] if a.lines else np.array([""] * len(ok))
    numeric_x = xv.dtype.kind == "f"
    xs = np.unique(xv[ok])
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    print(f"{label}{units_text(yunits)}: mean ± {a.spread} over seeds (n runs)")
    shown = [f"{x:g}" if numeric_x else str(x) for x in xs]
    print(f"{'':20s}" + "".join(f"{x:>22s}" for x in shown))
    for line in np.unique(lv[ok]):
        sel = ok & (lv == line)
        m, lo, hi, cells = [], [], [], []
        for x in xs:
            vals = y[sel & (xv == x)]
            if not len(vals):
                m.append(np.nan), lo.append(np.nan), hi.append(np.nan), cells.append(f"{'-':>22s}")
                continue
            mean = vals.mean()
            if a.spread == "minmax":
                lo.append(vals.min()), hi.append(vals.max())
            elif a.spread == "sd" and len(vals) > 1:
                sd = vals.std(ddof=1)
                lo.append(mean - sd), hi.append(mean + sd)
            else:
                lo.append(mean), hi.append(mean)
            m.append(mean)
            cells.append(f"{mean:.4g} ± {(hi[-1] - lo[-1]) / 2:.2g} ({len(vals)})")
        print(f"{str(line):20s}" + "".join(f"{c:>22s}" for c in cells))
        pos = xs if numeric_x else np.arange(len(xs))
        m, lo, hi = np.array(m), np.array(lo), np.array(hi)
        name = f"{a.lines} = {line}" if a.lines else None
        if a.spread == "minmax":
            (h,) = ax.plot(pos, m, marker="o", label=name)
            ax.fill_between(pos, lo, hi, color=h.get_color(), alpha=0.2, linewidth=0)
        elif a.spread == "sd":
            ax.errorbar(pos, m, yerr=[m - lo, hi - m], marker="o", capsize=3, label=name)
        else:
            ax.plot(pos, m, marker="o", label=name)
    if not numeric_x:
        ax.set_xticks(np.arange(len(xs)), shown)
    ax.set_xlabel(f"{x_name}{units_text(axes[x_name][1])}")
    ax.set_ylabel(f"{label}{units_text(yunits)}")
    seeds = len(np.unique(runs["seed"][ok]))
    spread = {"sd": "± 1 s.d.", "minmax": "min-max", "none": "mean"}[a.spread]
    ax.set_title(f"{os.path.basename(a.table)}: mean over {seeds} seed{'s' if seeds > 1 else ''}, {spread}",
                 fontsize=9)
    if a.lines:   # beside the axes, clear of the lines and error bars
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    out = a.output or f"{os.path.splitext(a.table)[0]}_{a.metric}_vs_{x_name}.png"
    fig.savefig(out, dpi=120, bbox_inches="tight")
    print(f"plot: {out}")


if __name__ == "__main__":
    main()
