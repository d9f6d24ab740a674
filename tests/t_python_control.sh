#!/usr/bin/env bash
# External controllers and the reinforcement-learning environments from Python (tests/python/test_control.py).
set -u
cd "$(dirname "$0")/.." || exit 1
make --no-print-directory -s python BUILD=build >/dev/null || { echo "FAIL python_build: make python"; exit 1; }
export PYTHONPATH="$PWD/python" WAVEFUEL_LIB="$PWD/lib/libwavefuel.so"
/usr/bin/python3 tests/python/test_control.py
