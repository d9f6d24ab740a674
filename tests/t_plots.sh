#!/usr/bin/env bash
# The plot scripts (tools/plot_timespace.py, plot_corridor.py, plot_sweep.py; Agg backend) on small results: each
# draws a PNG; the figures checked in the drawn matplotlib objects: the automated vehicles (a FollowerStopper group
# written into the scenario here) are black lines through exactly their trajectories from the file, the stacked
# time axes have the same horizontal extent, --vmax fixes the colour scale, no legend overlaps a data area. The
# wrong kind of file (missing, a directory, not HDF5, another wavefuel kind, no trajectories) gives a one-line message
# and exit status 2, no traceback. tools/wfplot.py's human-driver models equal the models docs/models.md documents.
set -u
cd "$(dirname "$0")/.." || exit 1
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
BUILD=${BUILD:-build}
PY=/usr/bin/python3
export MPLBACKEND=Agg
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

# A ring and a corridor with 2 FollowerStopper AVs among IDM humans, a ring without trajectories, a sweep table.
sed 's/    - {model: idm, fraction: 1.0, noise_mps2: 0.3}/    - {model: idm, count: 20, noise_mps2: 0.3}\n    - {name: av, model: follower_stopper, count: 2, params: {U_mps: 3}}/' \
  tests/data/tiny_ring.yaml >"$tmp/ring_av.yaml"
sed 's/    - {model: idm, fraction: 1.0, noise_mps2: 0.2}/    - {model: idm, fraction: 0.9, noise_mps2: 0.2}\n    - {name: av, model: follower_stopper, fraction: 0.1, params: {U_mps: 12}}/' \
  tests/data/tiny_corridor.yaml >"$tmp/corridor_av.yaml"
# The sweep: the AV ring, its AVs' desired speed against the humans' time gap, 2 seeds.
printf '%s\n' "scenario: $tmp/ring_av.yaml" "set: {time.duration_s: 8, output.trajectories: false}" "axes:" \
  '  - {key: "fleet.drivers[1].params.U_mps", values: [2, 3]}' '  - {key: "fleet.drivers[0].params.T_s", values: [1.2]}' \
  "seeds: 2" >"$tmp/sweep.yaml"
run() { "$BIN" run "$@" -q --force >"$tmp/run.log" 2>&1 || { ko "plots_setup" "$(cat "$tmp/run.log")"; exit 1; }; }
run "$tmp/ring_av.yaml" -o "$tmp/ring.h5" --set time.duration_s=60
run tests/data/tiny_ring.yaml -o "$tmp/notraj.h5" --set output.trajectories=false
run "$tmp/corridor_av.yaml" -o "$tmp/corridor.h5" --set time.duration_s=150
"$BIN" sweep "$tmp/sweep.yaml" -o "$tmp/sweep.h5" --threads 1 -q >"$tmp/run.log" 2>&1 || { ko "plots_setup" "$(cat "$tmp/run.log")"; exit 1; }
grep -q 'follower_stopper' "$tmp/ring_av.yaml" && grep -q 'follower_stopper' "$tmp/corridor_av.yaml" ||
  { ko "plots_setup" "the AV groups were not written into the scenarios"; exit 1; }
printf 'v,a\n1,2\n' >"$tmp/not_hdf5.csv"

# Messages: exit 2, a line "SCRIPT: ..." with the expected text (for a file: its path and what it is), no
# traceback, no figure written.
msg() {
  local name=$1 script=$2 file=$3 want=$4; shift 4
  out=$($PY "tools/$script" "$file" "$@" 2>&1 >/dev/null); rc=$?
  if [ "$rc" -eq 2 ] && ! grep -q Traceback <<<"$out" && grep -q "^$script: " <<<"$out" &&
     grep -qF -- "$want" <<<"$out" && [ ! -e "${file%.h5}.png" ]; then
    ok "plots_message_$name"
  else ko "plots_message_$name" "exit $rc: $out"; fi
}
for s in plot_timespace.py plot_corridor.py plot_sweep.py; do
  n=${s%.py}
  msg "${n}_missing" "$s" "$tmp/none.h5" "$tmp/none.h5: no such file"
  msg "${n}_directory" "$s" "$tmp" "$tmp: is a directory"
  msg "${n}_not_hdf5" "$s" "$tmp/not_hdf5.csv" "$tmp/not_hdf5.csv: not an HDF5 file"
done
msg timespace_sweep_table plot_timespace.py "$tmp/sweep.h5" "sweep.h5: a sweep table (wavefuel sweep), not a ring result"
msg timespace_corridor plot_timespace.py "$tmp/corridor.h5" "corridor.h5: a corridor result (wavefuel run, road.type: corridor), not a ring result (wavefuel run): draw it with tools/plot_corridor.py"
msg timespace_no_trajectories plot_timespace.py "$tmp/notraj.h5" "notraj.h5: no trajectories"
msg corridor_ring plot_corridor.py "$tmp/ring.h5" "ring.h5: a ring result (wavefuel run), not a corridor result"
msg sweep_corridor plot_sweep.py "$tmp/corridor.h5" "corridor.h5: a corridor result"
msg sweep_bad_where plot_sweep.py "$tmp/sweep.h5" "'x' is not a number" --metric fuel --where U_mps=x
msg timespace_bad_vmax plot_timespace.py "$tmp/ring.h5" "argument --vmax: invalid positive value: '-3'" --vmax -3

# Each plot draws, and what it draws.
$PY - "$tmp" <<'PY'
import contextlib, io, os, sys
import h5py
import matplotlib
matplotlib.use("Agg")
import matplotlib.figure
import numpy as np

tmp = sys.argv[1]
sys.path.insert(0, "tools")
import wfplot


def check(name, cond, why):
    print(f"PASS {name}" if cond else f"FAIL {name}: {why}")


def draw(script, *args):
    """Runs tools/SCRIPT's main() in this process and returns the figure it saved (and checks the PNG)."""
    saved = []
    orig = matplotlib.figure.Figure.savefig
    def capture(fig, path, **kw):
        saved.append((fig, path))
        orig(fig, path, **kw)
    matplotlib.figure.Figure.savefig = capture
    sys.argv = [f"tools/{script}.py", *args]
    mod = __import__(script)
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            mod.main()
    finally:
        matplotlib.figure.Figure.savefig = orig
    fig, path = saved[0]
    with open(path, "rb") as f:
        check(f"plots_{script}_png", f.read(8) == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG")
    return fig


def same_width(axes):
    pos = [a.get_position() for a in axes]
    return all(abs(p.x0 - pos[0].x0) < 1e-9 and abs(p.x1 - pos[0].x1) < 1e-9 for p in pos)


def legends_clear(fig):
    """No legend's box overlaps the data area of any axes."""
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    boxes = [a.get_window_extent(r) for a in fig.axes if not hasattr(a, "_colorbar")]
    for a in fig.axes:
        leg = a.get_legend()
        if leg is None:
            continue
        lb = leg.get_window_extent(r)
        for b in boxes:
            if lb.x0 < b.x1 - 1 and b.x0 < lb.x1 - 1 and lb.y0 < b.y1 - 1 and b.y0 < lb.y1 - 1:
                return False
    return True


def black_lines(ax):
    return [l for l in ax.get_lines() if matplotlib.colors.to_hex(l.get_color()) == "#000000"]


# Ring: the AVs are the vehicles of driver group "av" (2 of 22), from the file; their black lines pass through
# exactly their positions (x mod L) at the trajectory times.
ring = os.path.join(tmp, "ring.h5")
with h5py.File(ring, "r") as f:
    names = [wfplot.text(s) for s in f["drivers/name"][()]]
    av = np.flatnonzero(f["vehicles/group_id"][()] == names.index("av"))
    L = float(f["meta/road_length"][()])
    xs = f["trajectories/x"][:, av] % L
    check("plots_ring_two_avs", len(av) == 2, f"{len(av)} AVs in the file")
    check("plots_automated_groups", wfplot.automated_groups(f) == {names.index("av"): "follower_stopper"},
          str(wfplot.automated_groups(f)))
fig = draw("plot_timespace", ring, "--vmax", "30", "-o", os.path.join(tmp, "ring.png"))
ax1, ax2 = [a for a in fig.axes if not hasattr(a, "_colorbar")]
lines = black_lines(ax1)
drawn = sorted(np.sort(l.get_ydata()[np.isfinite(l.get_ydata())]).tolist() for l in lines)
want = sorted(np.sort(xs[:, k]).tolist() for k in range(len(av)))
check("plots_timespace_avs_marked", len(lines) == len(av) and all(np.allclose(d, w) for d, w in zip(drawn, want)),
      f"{len(lines)} black lines for {len(av)} AVs")
texts = [t.get_text() for t in ax1.get_legend().get_texts()] if ax1.get_legend() else []
check("plots_timespace_av_legend", texts == ["automated vehicles (follower_stopper)"], str(texts))
check("plots_timespace_sharex", same_width([ax1, ax2]) and ax1.get_xlim() == ax2.get_xlim(),
      f"{ax1.get_position()} {ax2.get_position()}")
check("plots_timespace_vmax", ax1.collections[0].get_clim() == (0, 30), str(ax1.collections[0].get_clim()))
check("plots_timespace_legends_clear", legends_clear(fig), "a legend overlaps a panel")
fig = draw("plot_timespace", ring, "-o", os.path.join(tmp, "ring2.png"))
with h5py.File(ring, "r") as f:
    vmax = f["trajectories/v"][()].max()
clim = [a for a in fig.axes if not hasattr(a, "_colorbar")][0].collections[0].get_clim()
check("plots_timespace_vmax_default", np.isclose(clim[1], vmax), f"{clim} against the fastest speed {vmax}")

# Corridor: the AV lines are the trajectory points of the serials whose trip is in group "av".
cor = os.path.join(tmp, "corridor.h5")
with h5py.File(cor, "r") as f:
    names = [wfplot.text(s) for s in f["drivers/name"][()]]
    avs = f["trips/serial"][()][f["trips/group_id"][()] == names.index("av")]
    ps = f["trajectories/serial"][()]
    n_av = len(np.intersect1d(avs, ps))
    pts = {s: np.sort(f["trajectories/x"][()][ps == s]) for s in avs}
fig = draw("plot_corridor", cor, "--vmax", "25", "-o", os.path.join(tmp, "corridor.png"))
ax1, ax2, ax3 = [a for a in fig.axes if not hasattr(a, "_colorbar")][:3]
lines = black_lines(ax1)
drawn = sorted(np.sort(l.get_ydata()).tolist() for l in lines)
want = sorted(v.tolist() for v in pts.values() if len(v))
check("plots_corridor_avs_marked", n_av >= 2 and len(lines) == n_av and
      all(np.allclose(d, w) for d, w in zip(drawn, want)), f"{len(lines)} black lines for {n_av} AVs on the road")
check("plots_corridor_sharex", same_width([ax1, ax2, ax3]) and ax1.get_xlim() == ax2.get_xlim(),
      f"{ax1.get_position()} {ax2.get_position()}")
check("plots_corridor_vmax", ax1.collections[0].get_clim() == (0, 25), str(ax1.collections[0].get_clim()))
check("plots_corridor_legends_clear", legends_clear(fig), "a legend overlaps a panel")
fig = draw("plot_corridor", cor, "--edie", "-o", os.path.join(tmp, "corridor_edie.png"))
check("plots_corridor_edie", len(black_lines(fig.axes[0])) == n_av, "AV lines over the Edie field")

# Sweep.
fig = draw("plot_sweep", os.path.join(tmp, "sweep.h5"), "--metric", "l_per_100km", "--x", "U_mps", "--lines", "T_s",
           "-o", os.path.join(tmp, "sweep.png"))
check("plots_sweep_legends_clear", legends_clear(fig), "a legend overlaps the axes")
PY

# The human-driver models of tools/wfplot.py are the models docs/models.md documents (its generated parameter
# tables), and with the controllers of docs/controllers.md they are every model of the registry (keydoc list).
$PY - "$BUILD/tools/keydoc" <<'PY'
import re, subprocess, sys
sys.path.insert(0, "tools")
import wfplot
doc = lambda p: set(re.findall(r"<!-- keydoc params (\w+) begin -->", open(p).read()))
humans, controllers = doc("docs/models.md"), doc("docs/controllers.md")
registry = {l.split()[1] for l in subprocess.run([sys.argv[1], "list"], capture_output=True, text=True).stdout
            .splitlines() if l.startswith("params ")}
ok = set(wfplot.HUMAN_MODELS) == humans and humans | controllers == registry and len(registry) > 0
print("PASS plots_human_models" if ok else
      f"FAIL plots_human_models: wfplot {sorted(wfplot.HUMAN_MODELS)}, models.md {sorted(humans)}, "
      f"controllers.md {sorted(controllers)}, registry {sorted(registry)}")
PY
