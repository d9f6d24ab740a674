"""Benchmarks that compare libraries (libwavefuel.so) from Python run each in a process of its own, since a process
loads one library: bench/corridor_vs_ring/steady.py, bench/corridor_threads/load_arrives.py. The script runs itself
again with --child and WAVEFUEL_LIB set; the child prints JSON."""
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def libs(specs):
    """[(name, path)] of --lib NAME=PATH arguments (default: this tree's lib/libwavefuel.so)."""
    return [tuple(x.split("=", 1)) for x in specs] or [("this", os.path.join(ROOT, "lib", "libwavefuel.so"))]


def run_child(script, path):
    """The JSON that `script --child` (with this process's other arguments) prints on library `path`."""
    env = dict(os.environ, WAVEFUEL_LIB=os.path.abspath(path))
    out = subprocess.run([sys.executable, os.path.abspath(script), "--child"] + sys.argv[1:], env=env, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out)
