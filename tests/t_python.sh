#!/usr/bin/env bash
# The Python package (docs/python.md) against bin/wavefuel: the ctypes mirrors against the C headers, energy bits,
# runs of rings and corridors (whole, in pieces, two at once) dataset by dataset, state views, errors
# (tests/python/test_python.py), and `pip install` of the package offline into a throw-away environment.
set -u
cd "$(dirname "$0")/.." || exit 1
PY=/usr/bin/python3
# lib/libwavefuel.so of the default build (`make test` builds it; this builds it when run alone).
make --no-print-directory -s python BUILD=build >/dev/null || { echo "FAIL python_build: make python"; exit 1; }
export PYTHONPATH="$PWD/python" WAVEFUEL_LIB="$PWD/lib/libwavefuel.so"
$PY tests/python/layout.py "${CC:-cc}"
$PY tests/python/test_python.py
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# pip with the system's numpy and setuptools (--system-site-packages), no index, no build isolation.
if $PY -m venv --system-site-packages --without-pip "$tmp/venv" 2>"$tmp/err" &&
   cp -r python "$tmp/src" && rm -rf "$tmp/src/build" "$tmp/src"/*.egg-info &&
   "$tmp/venv/bin/python" -m pip install -q --no-build-isolation --no-index "$tmp/src" >"$tmp/err" 2>&1; then
  # Outside the checkout: the library next to the installed package, the classes from $WAVEFUEL_VEHICLES.
  code='import sys, wavefuel
print(wavefuel.library_path().startswith(sys.argv[1]), float(wavefuel.energy.fuel("midsize_sedan", 20.0, 0.5)).hex())'
  got=$(cd "$tmp" && env -u PYTHONPATH -u WAVEFUEL_LIB WAVEFUEL_VEHICLES="$OLDPWD/vehicles" \
        "$tmp/venv/bin/python" -c "$code" "$tmp/venv" 2>&1)
  ref=$(printf 'v,a,theta\n20,0.5,0\n' | "${WAVEFUEL_BIN:-bin/wavefuel}" energy --class midsize_sedan | cut -d, -f4)
  ref=$($PY -c "import sys; print(float(sys.argv[1]).hex())" "$(tail -1 <<<"$ref")")
  if [ "$got" = "True $ref" ]; then echo "PASS python_pip_install"
  else echo "FAIL python_pip_install: got '$got', expected 'True $ref'"; fi
else
  echo "FAIL python_pip_install: $(tail -5 "$tmp/err")"
fi
