"""What the plot scripts (tools/plot_*.py) share: opening the kind of wavefuel file a script draws, with a message
and exit status 2, not a traceback, for a missing file, a directory, a file that is not HDF5 and a wavefuel file of
another kind (naming the kind and the script that draws it); which driver groups are automated; strings of HDF5.
"""
import os
import sys

import h5py

# The human-driver models of the car-following registry (src/models/cf/), the ones docs/models.md documents; every
# other model (the controllers of docs/controllers.md, plug-ins) drives an automated vehicle. tests/t_plots.sh
# checks this list against docs/models.md's generated parameter tables.
HUMAN_MODELS = ("idm", "ovm", "gipps")

# Every kind of file wavefuel writes that a plot may be handed: what it is, and what draws it.
KINDS = {
    "ring": ("a ring result (wavefuel run)", "draw it with tools/plot_timespace.py"),
    "corridor": ("a corridor result (wavefuel run, road.type: corridor)", "draw it with tools/plot_corridor.py"),
    "sweep": ("a sweep table (wavefuel sweep)", "draw it with tools/plot_sweep.py"),
    "cycle": ("a drive-cycle result (wavefuel cycle -o)", "no plot draws it (wavefuel info shows it)"),
    "table": ("a tabulated energy model (wavefuel table import)", "no plot draws it (wavefuel table info shows it)"),
}


def text(value):
    """A string dataset's value, or an element of one, as str."""
    value = value[()] if isinstance(value, h5py.Dataset) else value
    return value.decode() if isinstance(value, bytes) else str(value)


def kind(f):
    """The key of KINDS that describes the open file f, or None for an HDF5 file wavefuel did not write."""
    if "meta/kind" in f:
        k = text(f["meta/kind"])
        if k == "wavefuel sweep":
            return "sweep"
        if "cycle" in k:
            return "cycle"
    if "meta" in f and "summary" in f:
        return "corridor" if "edie" in f and "road" in f else "ring"
    if "fuel_gps" in f and "velocity_mps" in f:
        return "table"
    # wavefuel cycle -o: /CLASS/CYCLE/theta_GRADE/MODEL groups.
    for cls in f.values():
        if isinstance(cls, h5py.Group):
            for cyc in cls.values():
                if isinstance(cyc, h5py.Group) and any(n.startswith("theta_") for n in cyc):
                    return "cycle"
    return None


def fail(prog, message):
    """Prints 'prog: message' on stderr and exits with status 2 (bad input)."""
    print(f"{os.path.basename(prog)}: {message}", file=sys.stderr)
    sys.exit(2)


def open_file(path, wanted, prog):
    """The HDF5 file at path, open for reading, when its kind is one of wanted (keys of KINDS); else fail()."""
    want = " or ".join(KINDS[k][0] for k in wanted)
    if not os.path.exists(path):
        fail(prog, f"{path}: no such file (expected {want})")
    if os.path.isdir(path):
        fail(prog, f"{path}: is a directory (expected {want})")
    try:
        if not h5py.is_hdf5(path):
            fail(prog, f"{path}: not an HDF5 file (expected {want})")
        f = h5py.File(path, "r")
    except OSError as e:
        fail(prog, f"{path}: cannot open: {e}")
    k = kind(f)
    if k in wanted:
        return f
    f.close()
    if k is None:
        fail(prog, f"{path}: an HDF5 file that wavefuel did not write (expected {want})")
    fail(prog, f"{path}: {KINDS[k][0]}, not {want}: {KINDS[k][1]}")


def automated_groups(f):
    """{group_id: model} of the driver groups (/drivers) whose model is not a human-driver model."""
    models = [text(m) for m in f["drivers/model"][()]]
    return {g: m for g, m in enumerate(models) if m not in HUMAN_MODELS}


def positive(s):
    """argparse type: a float > 0."""
    v = float(s)
    if not v > 0:
        raise ValueError(s)
    return v
