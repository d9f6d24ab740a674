#!/usr/bin/python3
"""Two wavefuel result files hold the same results: every dataset and attribute outside /meta (the set of names,
dtype, shape and bytes; text by its values), and /meta/steps_done, /meta/completed and any /meta datasets named.

Used by tests/t_mpi.sh, bench/mpi_ring/run.py and bench/corridor_threads/run.py.

    h5same.py A.h5 B.h5 [meta/NAME...]    prints "N datasets, S steps"; exit 1 naming what differs
"""
import sys

import h5py
import numpy as np


def raw(x):
    """A value as bytes: text by its values (h5py returns object arrays of bytes or str)."""
    if isinstance(x, bytes):
        return x
    x = np.asarray(x)
    if x.dtype.kind == "O":
        return b"\0".join(v if isinstance(v, bytes) else str(v).encode() for v in x.ravel())
    return x.tobytes()


def compare(a_path, b_path, meta=()):
    """(number of datasets compared, names that differ)."""
    with h5py.File(a_path, "r") as a, h5py.File(b_path, "r") as b:
        def objects(f):
            out = {}
            f.visititems(lambda n, o: out.__setitem__(n, o) if not n.startswith("meta") else None)
            return out
        oa, ob = objects(a), objects(b)
        bad = [n + " (in one file only)" for n in sorted(set(oa) ^ set(ob))]
        count = 0
        for n in sorted(set(oa) & set(ob)):
            x, y = oa[n], ob[n]
            if sorted(x.attrs) != sorted(y.attrs) or any(raw(x.attrs[k]) != raw(y.attrs[k]) for k in x.attrs):
                bad.append(n + " (attributes)")
            if isinstance(x, h5py.Dataset):
                count += 1
                if x.dtype != y.dtype or x.shape != y.shape or raw(x[()]) != raw(y[()]):
                    bad.append(n)
        for n in ("meta/steps_done", "meta/completed") + tuple(meta):
            if raw(a[n][()]) != raw(b[n][()]):
                bad.append(f"{n} ({a[n][()]} vs {b[n][()]})")
    return count, bad


def main(argv):
    count, bad = compare(argv[1], argv[2], argv[3:])
    if bad:
        sys.exit("differ: " + ", ".join(bad[:8]) + (f" and {len(bad) - 8} more" if len(bad) > 8 else ""))
    if count <= 30:
        sys.exit(f"only {count} datasets")
    with h5py.File(argv[1], "r") as a:
        print(f"{count} datasets, {a['meta/steps_done'][()]} steps")


if __name__ == "__main__":
    main(sys.argv)
