#!/usr/bin/python3
"""Executable examples of the README and docs/*.md: runs every marked example and compares its output.

Marking: an HTML comment (invisible on GitHub) on the line just before a fenced block,

    <!-- example -->
    <!-- example tolerance=1e-3 setup="wavefuel run scenarios/sugiyama.yaml -q" cwd=output -->

In a marked block, a line starting with `$ ` is a command (continued on the next lines while a quote is open or
the line ends with `|`, `\\`, `&&` or `||`); the lines after it, up to the next command, are its expected output
(stdout and stderr together, as on a terminal). A line `...` stands for any number of output lines. Options:
  tolerance=R   relative tolerance of every number (default 1e-6: numbers agree to the digits printed)
  setup=CMD     a shell command run before the block, its output not compared
  cwd=DIR       the block's commands run in DIR (relative to the document's directory)
  status=N      the exit status every command of the block must give (default 0)

Each document runs in its own temporary directory, its marked blocks in document order (a later block may read
what an earlier one wrote), laid out like the repository: bin/wavefuel (the binary under test: $WAVEFUEL_BIN, default
bin/wavefuel), copies of scenarios/, vehicles/, tools/ and python/ (on PYTHONPATH), empty output/ and docs/, and
../shared/data (the data path: $WAVEFUEL_DATA, else the repository's ../shared/data). PATH starts with bin/, so
`wavefuel` and `./bin/wavefuel` both run the binary under test; OMP_NUM_THREADS=2, as the docs' figures were made.

Comparison, line by line after normalising both sides: runs of blanks are one blank; the figures that measure the
machine, not the code (the table TIMING: wall times, vehicle-steps/s, runs/h, load times) are masked; absolute paths
keep their last two components (`/work/main/vehicles/x.yaml` and `/tmp/t/repo/vehicles/x.yaml` are both
`.../vehicles/x.yaml`); numbers (not digits inside words: `us06`, hashes) agree within the tolerance, relative to the
documented value; all other text is equal.

Usage: docex.py [--root REPO] FILE.md...    prints "PASS example FILE:LINE" or "FAIL example FILE:LINE: why" per
block; exit status 1 when any block fails, 2 on a malformed mark.
"""
import argparse
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time

MARK = re.compile(r"^<!--\s*example\b(.*?)-->\s*$")
FENCE = re.compile(r"^```")
DEFAULT_TOLERANCE = 1e-6
COMMAND_TIMEOUT_S = 300

# Figures that measure the machine, not the code: the number in each pattern's group is masked on both sides.
TIMING = [re.compile(p) for p in (
    r"wall (\S+) s",                 # wavefuel run: "wall 0.046 s"
    r"(\S+) vehicle-steps/s",        # wavefuel run: throughput of the engine
    r"(\S+) runs/h",                 # wavefuel sweep: throughput
    r"now in (\S+) s",               # wavefuel sweep: "ran 45 now in 10.266 s"
    r"ok \((\S+) s\)",               # wavefuel sweep: each run's wall time
    r"loads in (\S+) ms",            # wavefuel table import: load time
)]
NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])")
ABS_PATH = re.compile(r"(?<![\w.~/])/[^\s:,()'\"`]*")
CONTINUED = ("|", "\\", "&&", "||")


class MarkError(Exception):
    pass


def parse_options(text, where):
    opts = {"tolerance": DEFAULT_TOLERANCE, "setup": None, "cwd": ".", "status": 0}
    try:
        words = shlex.split(text)
    except ValueError as e:
        raise MarkError(f"{where}: example mark: {e}")
    for w in words:
        key, eq, value = w.partition("=")
        if not eq or key not in opts:
            raise MarkError(f"{where}: example mark: unknown option '{w}' (known: {', '.join(opts)}, as KEY=VALUE)")
        try:
            opts[key] = type(opts[key])(value) if opts[key] is not None else value
        except ValueError:
            raise MarkError(f"{where}: example mark: {key}={value} is not a number")
    return opts


def complete(cmd):
    if cmd.rstrip().endswith(CONTINUED):
        return False
    try:
        shlex.split(cmd, comments=True)
    except ValueError:               # an open quote: the command goes on
        return False
    return True


def parse_block(lines, where):
    """[(command, [expected lines])] of a block's lines."""
    steps, i = [], 0
    while i < len(lines):
        if not lines[i].startswith("$ "):
            if steps:
                steps[-1][1].append(lines[i])
                i += 1
                continue
            raise MarkError(f"{where}: example block starts with '{lines[i]}', not a '$ ' command")
        cmd = lines[i][2:]
        i += 1
        while not complete(cmd) and i < len(lines):
            cmd += "\n" + lines[i]
            i += 1
        steps.append((cmd, []))
    return steps


def blocks(path):
    """(line number, options, steps) of every marked block of a Markdown file."""
    text = open(path, encoding="utf-8").read().split("\n")
    out = []
    for n, line in enumerate(text):
        m = MARK.match(line)
        if not m:
            continue
        where = f"{path}:{n + 1}"
        opts = parse_options(m.group(1), where)
        if n + 1 >= len(text) or not FENCE.match(text[n + 1]):
            raise MarkError(f"{where}: example mark not followed by a fenced block")
        end = next((k for k in range(n + 2, len(text)) if FENCE.match(text[k])), None)
        if end is None:
            raise MarkError(f"{where}: example block never closed")
        out.append((n + 2, opts, parse_block(text[n + 2:end], where)))
    return out


def normalise(line):
    for p in TIMING:
        line = p.sub(lambda m: m.group(0)[:m.start(1) - m.start(0)] + "<t>" + m.group(0)[m.end(1) - m.start(0):],
                     line)
    line = ABS_PATH.sub(lambda m: ".../" + "/".join(m.group(0).rstrip("/").split("/")[-2:]), line)
    return " ".join(line.split())


def same_line(expected, actual, tol):
    e, a = normalise(expected), normalise(actual)
    ne, na = NUMBER.findall(e), NUMBER.findall(a)
    if NUMBER.split(e) != NUMBER.split(a) or len(ne) != len(na):
        return False
    return all(abs(float(y) - float(x)) <= tol * abs(float(x)) for x, y in zip(ne, na))


def match(expected, actual, tol):
    """None when the actual lines match the expected ones (with `...` lines), else (expected index, actual index)
    of the mismatch that got furthest into the expected lines."""
    memo, worst = {}, [(-1, -1)]

    def go(i, j):
        if (i, j) in memo:
            return memo[(i, j)]
        if i == len(expected):
            r = j == len(actual)
        elif expected[i].strip() == "...":
            r = any(go(i + 1, k) for k in range(j, len(actual) + 1))
        else:
            r = j < len(actual) and same_line(expected[i], actual[j], tol) and go(i + 1, j + 1)
        if not r and i > worst[0][0] and expected[i:i + 1] != ["..."]:
            worst[0] = (i, j)
        memo[(i, j)] = r
        return r

    sys.setrecursionlimit(max(10000, 4 * (len(expected) + len(actual))))
    return None if go(0, 0) else worst[0]


def sandbox(root, tmp):
    """The repository's layout in tmp/repo (see the module's doc); returns (directory, environment)."""
    work = os.path.join(tmp, "repo")
    os.makedirs(os.path.join(work, "bin"))
    binary = os.path.abspath(os.path.join(root, os.environ.get("WAVEFUEL_BIN", "bin/wavefuel")))
    os.symlink(binary, os.path.join(work, "bin", "wavefuel"))
    for d in ("scenarios", "vehicles", "tools"):
        shutil.copytree(os.path.join(root, d), os.path.join(work, d),
                        ignore=shutil.ignore_patterns("__pycache__"))
    for d in ("output", "docs"):
        os.makedirs(os.path.join(work, d))
    # The Python package with the libwavefuel.so that `make python` copies into it (docs/python.md).
    shutil.copytree(os.path.join(root, "python"), os.path.join(work, "python"),
                    ignore=shutil.ignore_patterns("__pycache__", "build", "*.egg-info"))
    data = os.environ.get("WAVEFUEL_DATA") or os.path.join(root, "..", "shared", "data")
    os.makedirs(os.path.join(tmp, "shared"))
    os.symlink(os.path.abspath(data), os.path.join(tmp, "shared", "data"))
    env = dict(os.environ, PATH=os.path.join(work, "bin") + os.pathsep + os.environ.get("PATH", ""),
               WAVEFUEL_VEHICLES=os.path.join(work, "vehicles"), WAVEFUEL_DATA=os.path.join(tmp, "shared", "data"),
               OMP_NUM_THREADS="2", MPLBACKEND="Agg", LC_ALL="C", PYTHONDONTWRITEBYTECODE="1",
               PYTHONPATH=os.path.join(work, "python"))
    env.pop("WAVEFUEL_BIN", None)
    return work, env


def shell(cmd, cwd, env):
    try:
        p = subprocess.run(["bash", "-c", "set -o pipefail\n" + cmd], cwd=cwd, env=env, stdin=subprocess.DEVNULL,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=COMMAND_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return None, [f"(killed after {COMMAND_TIMEOUT_S} s)"]
    lines = p.stdout.decode("utf-8", "replace").split("\n")
    while lines and not lines[-1].strip():
        lines.pop()
    return p.returncode, lines


def run_block(steps, opts, work, env):
    """None when every command gives its expected output, else why not."""
    cwd = os.path.join(work, opts["cwd"])
    if not os.path.isdir(cwd):
        return f"cwd={opts['cwd']}: no such directory in the document's directory"
    if opts["setup"]:
        rc, out = shell(opts["setup"], cwd, env)
        if rc != 0:
            return f"setup `{opts['setup']}` exited {rc}: " + " | ".join(out[-5:])
    for cmd, expected in steps:
        rc, out = shell(cmd, cwd, env)
        first = cmd.split("\n")[0]
        if rc != opts["status"]:
            return f"`{first}` exited {rc} (expected {opts['status']}): " + " | ".join(out[-5:])
        while expected and not expected[-1].strip():
            expected = expected[:-1]
        bad = match(expected, out, opts["tolerance"])
        if bad is not None:
            i, j = bad
            want = expected[i] if i < len(expected) else "(end of output)"
            got = out[j] if 0 <= j < len(out) else "(end of output)"
            return (f"`{first}` output line {j + 1}: expected '{want.strip()}', got '{got.strip()}' "
                    f"(tolerance {opts['tolerance']:g})")
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--root", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."),
                    help="the repository (default: this script's ..)")
    ap.add_argument("docs", nargs="+")
    args = ap.parse_args()
    root = os.path.abspath(args.root)
    failed = 0
    for doc in args.docs:
        try:
            marked = blocks(doc)
        except (MarkError, OSError) as e:
            print(f"FAIL example {doc}: {e}")
            return 2
        if not marked:
            continue
        with tempfile.TemporaryDirectory(prefix="docex.") as tmp:
            work, env = sandbox(root, tmp)
            for line, opts, steps in marked:
                start = time.monotonic()
                why = run_block(steps, opts, work, env)
                took = time.monotonic() - start
                if why is None:
                    print(f"PASS example {doc}:{line} ({len(steps)} commands, {took:.1f} s)")
                else:
                    failed += 1
                    print(f"FAIL example {doc}:{line}: {why}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
