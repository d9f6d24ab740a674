#!/usr/bin/python3
"""Result fingerprints: the regression check that keeps every dataset of every scenario bit-identical.

Runs each case of tests/fingerprint/cases.txt with bin/wavefuel, and reduces every dataset of the result file to
one line: path, dtype, shape, units, description and the SHA-256 of its bytes. /meta's wall-clock entries
(wall_time_s, phase_time, start_time), the build's git hash and version are left out: they differ between runs.

  fingerprint.py check             compare with tests/fingerprint/expected.txt (PASS/FAIL per case)
  fingerprint.py update            rewrite expected.txt (only when a change of results is deliberate)
  fingerprint.py check --keep DIR  also keep the result files in DIR
  fingerprint.py diff OLD NEW      largest relative difference of every dataset between two kept directories
"""
import hashlib
import os
import subprocess
import sys
import tempfile

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
CASES = os.path.join(HERE, "cases.txt")
EXPECTED = os.path.join(HERE, "expected.txt")
SKIP = {"/meta/wall_time_s", "/meta/phase_time", "/meta/start_time", "/meta/git_hash", "/meta/version",
        "/meta/written", "/timing/sweep_wall_time", "/timing/wall_time", "/timing/worker"}


def cases():
    out = []
    with open(CASES) as f:
        for line in f:
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            name, threads, scenario, *sets = line.split("|")
            out.append((name, threads, scenario, sets))
    return out


def attr_text(obj, key):
    v = obj.attrs.get(key)
    if v is None:
        return "-"
    if isinstance(v, bytes):
        v = v.decode()
    return str(v).replace(" ", "_")


def fingerprint_file(path):
    lines = []

    def visit(name, obj):
        full = "/" + name
        if not isinstance(obj, h5py.Dataset) or full in SKIP:
            return
        data = obj[()]
        if isinstance(data, bytes):
            raw = data
        elif isinstance(data, np.ndarray) and data.dtype.kind == "O":
            raw = b"\0".join(x if isinstance(x, bytes) else str(x).encode() for x in data.ravel())
        else:
            raw = np.ascontiguousarray(data).tobytes()
        digest = hashlib.sha256(raw).hexdigest()[:20]
        shape = "x".join(str(s) for s in obj.shape) or "scalar"
        lines.append(f"{full} {obj.dtype.str} {shape} {attr_text(obj, 'units')} "
                     f"{hashlib.sha256(attr_text(obj, 'description').encode()).hexdigest()[:8]} {digest}")

    with h5py.File(path, "r") as f:
        f.visititems(visit)
    return lines


def run_case(name, threads, scenario, sets, outdir):
    out = os.path.join(outdir, name + ".h5")
    # A case whose name starts with "sweep" runs `wavefuel sweep` on a sweep file.
    verb = "sweep" if name.startswith("sweep") else "run"
    cmd = [os.environ.get("WAVEFUEL_BIN", os.path.join(ROOT, "bin/wavefuel")), verb, scenario, "-o", out,
           "--threads", threads, "-q", "--force"]
    for s in sets:
        cmd += ["--set", s]
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if r.returncode != 0:
        return None, f"exit {r.returncode}: {r.stderr.strip()}"
    return out, ""


def compute(keep=None):
    res = {}
    with tempfile.TemporaryDirectory() as tmp:
        outdir = keep or tmp
        os.makedirs(outdir, exist_ok=True)
        for name, threads, scenario, sets in cases():
            path, msg = run_case(name, threads, scenario, sets, outdir)
            res[name] = fingerprint_file(path) if path else ["RUN FAILED " + msg]
    return res


def read_expected():
    exp, cur = {}, None
    with open(EXPECTED) as f:
        for line in f:
            line = line.rstrip("\n")
            if line.startswith("== "):
                cur = line[3:]
                exp[cur] = []
            elif line and cur:
                exp[cur].append(line)
    return exp


def main(argv):
    keep = None
    if "--keep" in argv:
        keep = argv[argv.index("--keep") + 1]
    mode = argv[1] if len(argv) > 1 else "check"
    if mode == "diff":
        return diff_dirs(argv[2], argv[3])
    res = compute(keep)
    if mode == "update":
        with open(EXPECTED, "w") as f:
            f.write("# Written by tests/fingerprint/fingerprint.py update: path dtype shape units "
                    "description-hash data-hash\n")
            for name, lines in res.items():
                f.write(f"== {name}\n" + "\n".join(lines) + "\n")
        print(f"wrote {EXPECTED}: {len(res)} cases, {sum(len(v) for v in res.values())} datasets")
        return 0
    exp = read_expected()
    failed = 0
    for name, lines in res.items():
        want = exp.get(name)
        if want is None:
            print(f"FAIL fingerprint {name}: no expected fingerprint (run fingerprint.py update)")
            failed += 1
            continue
        if lines == want:
            print(f"PASS fingerprint {name} ({len(lines)} datasets)")
            continue
        failed += 1
        a, b = set(want), set(lines)
        print(f"FAIL fingerprint {name}: {len(a - b)} expected lines differ")
        for line in sorted(a - b)[:8]:
            print("    expected:", line)
        for line in sorted(b - a)[:8]:
            print("    got:     ", line)
    for name in exp:
        if name not in res:
            print(f"FAIL fingerprint {name}: expected but not in cases.txt")
            failed += 1
    return 1 if failed else 0


def diff_dirs(old, new):
    """Largest relative difference per dataset between result files of the same cases."""
    worst = 0.0
    for fn in sorted(os.listdir(old)):
        if not fn.endswith(".h5") or not os.path.exists(os.path.join(new, fn)):
            continue
        with h5py.File(os.path.join(old, fn)) as fa, h5py.File(os.path.join(new, fn)) as fb:
            def visit(name, obj):
                nonlocal worst
                full = "/" + name
                if not isinstance(obj, h5py.Dataset) or full in SKIP:
                    return
                if name not in fb:
                    print(f"{fn} {full}: missing in new")
                    return
                a, b = obj[()], fb[name][()]
                if isinstance(a, np.ndarray) and a.dtype.kind in "fiu" and a.shape == np.shape(b):
                    a64, b64 = a.astype(np.float64), np.asarray(b, dtype=np.float64)
                    with np.errstate(invalid="ignore", divide="ignore"):
                        same = (a64 == b64) | (np.isnan(a64) & np.isnan(b64))
                        rel = np.where(same, 0.0, np.abs(a64 - b64) / np.maximum(np.abs(a64), np.abs(b64)))
                    m = float(np.max(rel)) if rel.size else 0.0
                    if m > 0:
                        print(f"{fn} {full}: max rel diff {m:.3e}")
                        worst = max(worst, m)
                elif isinstance(a, (float, int, np.floating, np.integer)) and a != b:
                    m = abs(float(a) - float(b)) / max(abs(float(a)), abs(float(b)))
                    print(f"{fn} {full}: rel diff {m:.3e}")
                    worst = max(worst, m)
                elif not isinstance(a, (float, int, np.floating, np.integer, np.ndarray)) and a != b:
                    print(f"{fn} {full}: differs")
            fa.visititems(visit)
    print(f"largest relative difference {worst:.3e}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
