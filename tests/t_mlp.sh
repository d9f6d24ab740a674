#!/usr/bin/env bash
# Learned controllers (`model: mlp`): the network against numpy and PyTorch, runs with 1 and 2 threads, resumed
# runs, a linear law and a constant set speed against their equivalents (tests/python/test_mlp.py).
set -u
cd "$(dirname "$0")/.." || exit 1
make --no-print-directory -s python BUILD=build >/dev/null || { echo "FAIL python_build: make python"; exit 1; }
export PYTHONPATH="$PWD/python" WAVEFUEL_LIB="$PWD/lib/libwavefuel.so"
/usr/bin/python3 tests/python/test_mlp.py
