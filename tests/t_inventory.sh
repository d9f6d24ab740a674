#!/usr/bin/env bash
# Adding to an inventory never breaks a test (issue 16, "Tests derive inventories"):
#  1. a seventh vehicle class: vehicles/ plus one more class file (a copy of the compact sedan under another
#     name and label) in a temporary directory named by $WAVEFUEL_VEHICLES (src/models/energy/vehicle.c: searched
#     before the repository's vehicles/); the tests that depend on the class list (test_cycle: every class through
#     synthetic cycles and the protocol; test_vehicle; t_energy_cli: --list) must still pass, `wavefuel energy
#     --list` must list every class file, and a ring of the new class must run (t_cycle_cli names its classes);
#  2. a seventh car-following model: the tree copied (with its build, so only what changes is rebuilt), one model
#     file (src/models/cf/ovm.c under another name) and one registry line added in src/models/cf/registry.c; the
#     library, the CLI and the test that loops over wf_cf_models[] (test_cf; the only one: `grep -l wf_cf_models
#     tests/`) built there (relinking every test binary would take 15 s more); test_cf must pass, the new
#     name must appear in the unknown-model message, and a ring driven by it must give the same vehicles, bit for
#     bit, as the same ring driven by `ovm`.
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
BUILD=${BUILD:-build}
PY=/usr/bin/python3
ROOT=$(pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }
# no_fail NAME LOG: the log has PASS lines and no FAIL line.
no_fail() {
  if grep -q '^PASS ' "$2" && ! grep -q '^FAIL ' "$2"; then ok "$1"; else ko "$1" "$(grep '^FAIL' "$2" | head -5)"; fi
}

# ---- 1. One more vehicle class.
mkdir -p "$tmp/vehicles"
cp vehicles/*.yaml "$tmp/vehicles/"
sed -e 's/^name: .*/name: Inventory Test Sedan/' vehicles/compact_sedan.yaml >"$tmp/vehicles/zz_inventory_sedan.yaml"
n_files=$(ls "$tmp/vehicles"/*.yaml | wc -l)
export WAVEFUEL_VEHICLES="$tmp/vehicles"
list=$("$BIN" energy --list 2>&1)
rows=$(printf '%s\n' "$list" | awk 'NR > 1 && NF >= 6' | wc -l)
if printf '%s\n' "$list" | grep -q '^zz_inventory_sedan ' && [ "$rows" -eq "$n_files" ]; then ok inventory_class_listed
else ko inventory_class_listed "$rows rows for $n_files class files: $list"; fi
"$BUILD/tests/test_cycle" >"$tmp/cycle.log" 2>&1; no_fail inventory_class_test_cycle "$tmp/cycle.log"
"$BUILD/tests/test_vehicle" >"$tmp/vehicle.log" 2>&1; no_fail inventory_class_test_vehicle "$tmp/vehicle.log"
bash tests/t_energy_cli.sh >"$tmp/energy.log" 2>&1; no_fail inventory_class_t_energy_cli "$tmp/energy.log"
if "$BIN" run tests/data/tiny_ring.yaml -q -o "$tmp/extra.h5" --set time.duration_s=6 --set output.trajectories=false \
     --set 'fleet.classes[0].class=zz_inventory_sedan' 2>"$tmp/run.err" &&
   $PY -c 'import h5py, sys; f = h5py.File(sys.argv[1]); assert b"zz_inventory_sedan" in list(f["classes/name"][:])' \
     "$tmp/extra.h5"; then ok inventory_class_runs
else ko inventory_class_runs "$(cat "$tmp/run.err")"; fi
export WAVEFUEL_VEHICLES=

# ---- 2. One more car-following model, in a copy of the tree.
copy="$tmp/tree"
mkdir -p "$copy"
cp -a Makefile include src tests examples fuzz vehicles "$copy/"
# The default build's objects (build/, not $BUILD: a sanitizer build's objects need its flags) keep the rebuild to
# the changed files; without them the copy builds from scratch.
for d in build bin lib; do [ -d "$d" ] && cp -a "$d" "$copy/"; done
sed -e 's/wf_cf_ovm\b/wf_cf_zz_ovm_copy/g' -e 's/"ovm"/"zz_ovm_copy"/' src/models/cf/ovm.c \
  >"$copy/src/models/cf/zz_ovm_copy.c"
$PY - "$copy/src/models/cf/registry.c" <<'PY'
import re, sys
p = sys.argv[1]
s = open(p).read()
s, n = re.subn(r"(const WfCfModel \*const wf_cf_models\[\] = \{[^}]*?)NULL\}",
               r"\1&wf_cf_zz_ovm_copy, NULL}", s, count=1, flags=re.S)
assert n == 1, "registry array not found"
s = s.replace("const WfCfModel *const wf_cf_models[]", "extern const WfCfModel wf_cf_zz_ovm_copy;\n"
              "const WfCfModel *const wf_cf_models[]", 1)
open(p, "w").write(s)
PY
start=$SECONDS
if ! grep -q 'wf_cf_zz_ovm_copy' "$copy/src/models/cf/zz_ovm_copy.c"; then
  ko inventory_model_build "the model copy has no wf_cf_zz_ovm_copy"
elif env -u CFLAGS -u LDFLAGS -u MAKEFLAGS -u MFLAGS -u MAKELEVEL make -C "$copy" -j2 WERROR=1 BUILD=build \
       bin/wavefuel lib/libwavefuel.a build/tests/test_cf >"$tmp/make.log" 2>&1; then
  ok inventory_model_build
  echo "  (model build: $((SECONDS - start)) s)"
  (cd "$copy" && WAVEFUEL_BIN=bin/wavefuel build/tests/test_cf) >"$tmp/cf.log" 2>&1
  no_fail inventory_model_test_cf "$tmp/cf.log"
  msg=$("$copy/bin/wavefuel" run tests/data/tiny_ring.yaml -q -o "$tmp/x.h5" --set 'fleet.drivers[0].model=nosuch' 2>&1)
  if printf '%s' "$msg" | grep -q 'zz_ovm_copy'; then ok inventory_model_listed; else ko inventory_model_listed "$msg"; fi
  common=(--set time.duration_s=6 --set output.trajectories=false)
  if "$copy/bin/wavefuel" run tests/data/tiny_ring.yaml -q -o "$tmp/ovm.h5" "${common[@]}" \
       --set 'fleet.drivers[0].model=ovm' &&
     "$copy/bin/wavefuel" run tests/data/tiny_ring.yaml -q -o "$tmp/copy.h5" "${common[@]}" \
       --set 'fleet.drivers[0].model=zz_ovm_copy' &&
     $PY - "$tmp/ovm.h5" "$tmp/copy.h5" <<'PY'
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1]), h5py.File(sys.argv[2])
assert b["drivers/model"][0] == b"zz_ovm_copy", b["drivers/model"][:]
for g in ("vehicles", "timeseries", "summary"):
    for n in a[g]:
        x, y = a[g][n][()], b[g][n][()]
        assert np.asarray(x).tobytes() == np.asarray(y).tobytes(), f"{g}/{n} differs"
PY
  then ok inventory_model_runs_as_ovm; else ko inventory_model_runs_as_ovm "runs or comparison failed"; fi
else
  ko inventory_model_build "$(grep -E 'error|Error' "$tmp/make.log" | head -5)"
fi
