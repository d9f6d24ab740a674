#!/usr/bin/env bash
# `wavefuel cycle` and `wavefuel table` end to end: table import (the release's sample, overwrite refusal,
# malformed input), a single drive-cycle run whose fuel is recomputed here with awk from `wavefuel energy`
# evaluations, its HDF5 output (checked with h5py), cycle names and data directories, a tabulated class file,
# the protocol with a table beside the polynomial, and the command-line errors (exit status 2).
# Prints "PASS name" / "FAIL name: why" per case.
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
PY=/usr/bin/python3
DATA=${WAVEFUEL_TEST_DATA:-$(cd "$(dirname "$0")/.." && pwd)/../shared/data}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }
have_h5py() { $PY -c 'import h5py, numpy' 2>/dev/null; }

out=$($BIN cycle --help); rc=$?
if [ $rc -eq 0 ] && echo "$out" | grep -q 'usage: wavefuel cycle --class'; then ok cycle_help; else ko cycle_help "rc=$rc"; fi
out=$($BIN table --help); rc=$?
if [ $rc -eq 0 ] && echo "$out" | grep -q 'wavefuel table import IN.csv -o OUT.h5'; then ok table_help; else ko table_help "rc=$rc"; fi

if [ ! -f "$DATA/cycles/udds.csv" ]; then
  echo "SKIP cycle runs: no $DATA/cycles (the shared data directory)"
  exit 0
fi

# ---- table import ------------------------------------------------------------------------------------------
sample="$DATA/semiprincipled/midsize_suv_head.csv"
if [ -f "$sample" ]; then
  out=$($BIN table import "$sample" -o "$tmp/head.h5"); rc=$?
  if [ $rc -eq 0 ] && echo "$out" | grep -q '1 speeds \[0, 0\] m/s x 3 accelerations \[3.84, 4\] m/s^2 x 21 grades \[-0.03, 0.03\] rad = 63 points' \
     && echo "$out" | grep -q 'infeasible nodes 24 of 63'; then
    ok import_sample
  else
    ko import_sample "rc=$rc: $out"
  fi
  err=$($BIN table import "$sample" -o "$tmp/head.h5" 2>&1 >/dev/null); rc=$?
  if [ $rc -eq 2 ] && echo "$err" | grep -q 'exists'; then ok import_no_overwrite; else ko import_no_overwrite "rc=$rc $err"; fi
  $BIN table import "$sample" -o "$tmp/head.h5" --force >/dev/null; rc=$?
  if [ $rc -eq 0 ] && [ ! -e "$tmp/head.h5.partial" ]; then ok import_force; else ko import_force "rc=$rc"; fi
  out=$($BIN table info "$tmp/head.h5"); rc=$?
  if [ $rc -eq 0 ] && echo "$out" | grep -q '= 63 points'; then ok table_info; else ko table_info "rc=$rc"; fi
else
  echo "SKIP import_sample: no $sample"
fi
printf 'Velocity,Acceleration,Road Grade,Fuel Rate,Infeasible\n0,1,0,1.5,0\n0,1,0.01,1.6,0\n0,0,0,1.1,0\n' >"$tmp/bad.csv"
err=$($BIN table import "$tmp/bad.csv" -o "$tmp/bad.h5" 2>&1 >/dev/null); rc=$?
if [ $rc -eq 2 ] && echo "$err" | grep -q 'not a regular grid: no row for Velocity=0, Acceleration=0, Road Grade=0.01' \
   && [ ! -e "$tmp/bad.h5" ] && [ ! -e "$tmp/bad.h5.partial" ]; then
  ok import_malformed
else
  ko import_malformed "rc=$rc $err"
fi

# ---- a single run, recomputed from `wavefuel energy` -------------------------------------------------------
# awk forms a[i] = (v[i+1]-v[i])/dt_i (0 last) and dt, `wavefuel energy` evaluates the model, awk sums f dt.
awk -F, 'NR > 1 { t[n] = $1; v[n] = $2; n++ } END {
  print "v,a,theta"; for (i = 0; i < n; i++) printf "%.17g,%.17g,0.01\n", v[i], (i < n - 1 ? (v[i+1] - v[i]) / (t[i+1] - t[i]) : 0) }' \
  "$DATA/cycles/udds.csv" >"$tmp/udds_pts.csv"
want=$($BIN energy --class midsize_suv "$tmp/udds_pts.csv" | paste -d, - <(echo dt; awk -F, 'NR > 1 { t[n++] = $1 } END {
  for (i = 0; i < n; i++) printf "%.17g\n", (i < n - 1 ? t[i+1] - t[i] : 0) }' "$DATA/cycles/udds.csv") |
  awk -F, 'NR > 1 { s += $4 * $7; d += $1 * $7 } END { printf "%.3f %.3f", s, d / 1000 }')
out=$($BIN cycle --class midsize_suv --grade 0.01 --scheme first-order udds -o "$tmp/run.h5"); rc=$?
got=$(echo "$out" | awk '$1 == "circles_polynomial" { printf "%s", $3 }')
km=$(echo "$out" | awk '$1 == "cycle" { for (i = 1; i <= NF; i++) if ($(i+1) == "km") print $i }')
if [ $rc -eq 0 ] && [ "$got $km" = "$want" ]; then ok single_run_fuel; else ko single_run_fuel "rc=$rc got '$got $km' want '$want'"; fi
if echo "$out" | grep -q 'density   750.0 g/L = 2839 g per US gallon'; then ok density_stated; else ko density_stated "$out"; fi
if have_h5py; then
  chk=$($PY - "$tmp/run.h5" <<'EOF'
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
g = f["midsize_suv/udds/theta_+0.0100/circles_polynomial"]
t, fuel = g["time_s"][:], g["fuel_gps"][:]
dt = np.append(np.diff(t), 0.0)
assert len(t) == 1370 and g.attrs["grade_rad"] == 0.01 and g.attrs["project"] == 0
assert g.attrs["scheme"] in ("first-order", b"first-order") and (g["weight_s"][:] == dt).all()
assert abs((fuel * dt).sum() - g["fuel_g"][()]) <= 1e-9 * g["fuel_g"][()]
assert abs(g["distance_m"][()] - (g["speed_mps"][:] * dt).sum()) < 1e-6
assert np.allclose(g["power_kw"][:], fuel * 42.36, rtol=1e-15, atol=0)
for name in ("time_s", "speed_mps", "accel_mps2", "weight_s", "fuel_gps", "power_kw", "flag", "fuel_g", "mpg"):
    assert "units" in g[name].attrs, name
print("ok")
EOF
)
  if [ "$chk" = ok ]; then ok single_run_hdf5; else ko single_run_hdf5 "$chk"; fi
else
  echo "SKIP single_run_hdf5: no h5py"
fi
# The default scheme is the table's first row, named in the output; the release's scheme is recomputed by
# tests/cycle_schemes_check.py below.
first=$($BIN cycle --help | awk '/^Schemes/ { getline; print $1; exit }')
if [ -n "$first" ] && $BIN cycle --class midsize_suv udds | grep -q "^scheme    $first: "; then ok default_scheme_first
else ko default_scheme_first "first row '$first'"; fi
err=$($BIN cycle --class midsize_suv udds -o "$tmp/run.h5" 2>&1 >/dev/null); rc=$?
if [ $rc -eq 2 ] && echo "$err" | grep -q 'exists'; then ok run_no_overwrite; else ko run_no_overwrite "rc=$rc $err"; fi
$BIN cycle --class midsize_suv udds -o "$tmp/run.h5" --force >/dev/null; rc=$?
if [ $rc -eq 0 ] && [ ! -e "$tmp/run.h5.partial" ]; then ok run_force; else ko run_force "rc=$rc"; fi

# ---- cycle names and data directories ----------------------------------------------------------------------
mkdir -p "$tmp/data/cycles"
printf 'time_s,speed_mps\n0,10\n100,10\n' >"$tmp/data/cycles/flat.csv"
a=$($BIN cycle --class compact_sedan --cycles "$tmp/data" flat | awk '$1 == "circles_polynomial" { print $3 }')
b=$(WAVEFUEL_DATA="$tmp/data" $BIN cycle --class compact_sedan flat | awk '$1 == "circles_polynomial" { print $3 }')
c=$($BIN cycle --class compact_sedan "$tmp/data/cycles/flat.csv" | awk '$1 == "circles_polynomial" { print $3 }')
# 100 s at 10 m/s: (c0 + c1 10 + c3 1000) * 100 from the compact sedan's parameters.
w=$(awk 'BEGIN { printf "%.3f", (0.15918 + 0.013463 * 10 + 3.1889e-05 * 1000) * 100 }')
if [ "$a" = "$w" ] && [ "$b" = "$w" ] && [ "$c" = "$w" ]; then ok names_and_data_dirs; else ko names_and_data_dirs "$a $b $c want $w"; fi
err=$($BIN cycle --class compact_sedan --cycles "$tmp/data" hill 2>&1 >/dev/null); rc=$?
if [ $rc -eq 2 ] && echo "$err" | grep -q "cycle 'hill' not found.*(cycles there: flat)"; then ok unknown_cycle; else ko unknown_cycle "rc=$rc $err"; fi

# ---- a tabulated class file ----------------------------------------------------------------------------------
# Sample the midsize SUV's explicit model with `wavefuel energy` on a coarse grid in the release's format.
awk 'BEGIN { for (i = 0; i <= 37; i++) for (j = 70; j >= 0; j--) for (k = -3; k <= 3; k++)
  printf "%.15g,%.15g,%.15g\n", i, (j - 32) / 10, k / 100 }' |
  $BIN energy --class midsize_suv |
  awk -F, 'NR == 1 { print "Velocity,Acceleration,Road Grade,Fuel Rate,Infeasible"; next }
           { printf "%.15g,%.15g,%.15g,%.15g,%d\n", $1, $2, $3, $4, $6 == 1 }' >"$tmp/suv.csv"
mkdir -p "$tmp/classes/tables"
$BIN table import "$tmp/suv.csv" -o "$tmp/classes/tables/suv.h5" >/dev/null
cat >"$tmp/classes/suv_tab.yaml" <<'EOF'
name: Midsize SUV (tabulated)
duty: light
fuel: gasoline
mass_kg: 1897
length_m: 4.8
kw_per_gps: 42.36
energy_model: tabulated
table: tables/suv.h5
EOF
out=$($BIN cycle --class "$tmp/classes/suv_tab.yaml" --scheme first-order udds); rc=$?
row=$(echo "$out" | awk '$1 == "tabulated"')
if [ $rc -eq 0 ] && echo "$row" | awk '$2 == "on" && $(NF-2) == "0" && $NF == "1370" { f = 1 } END { exit !f }'; then
  ok tabulated_class_run
else
  ko tabulated_class_run "rc=$rc: $out"
fi
off=$($BIN cycle --class "$tmp/classes/suv_tab.yaml" --no-project udds | awk '$1 == "tabulated" { print $2 }')
if [ "$off" = off ]; then ok no_project_option; else ko no_project_option "$off"; fi
out=$(printf 'v,a,theta\n10,0.5,0\n' | $BIN energy --class "$tmp/classes/suv_tab.yaml"); rc=$?
if [ $rc -eq 0 ] && [ "$(echo "$out" | wc -l)" -eq 2 ]; then ok tabulated_class_energy; else ko tabulated_class_energy "rc=$rc"; fi

# ---- the protocol with a table beside the polynomial ------------------------------------------------------------
{ cat "$(dirname "$0")/../vehicles/midsize_suv.yaml"; echo "table: tables/suv.h5"; } >"$tmp/classes/midsize_suv.yaml"
out=$($BIN cycle --protocol --no-project --class "$tmp/classes/midsize_suv.yaml" -o "$tmp/prot.h5"); rc=$?
n_rel=$(echo "$out" | grep -c '| rel. diff |')
if [ $rc -eq 0 ] && [ "$n_rel" -eq 4 ] && echo "$out" | grep -q '^| ALL | rel. diff, duration-weighted mean (paper) |' \
   && echo "$out" | grep -q '^| ALL | rel. diff, total fuel over total fuel |' \
   && echo "$out" | grep -q 'HHDDT high speed is not run'; then
  ok protocol_table_beside
else
  ko protocol_table_beside "rc=$rc rel rows=$n_rel"
fi
out2=$($BIN cycle --protocol --no-project --class midsize_suv --table "midsize_suv=$tmp/classes/tables/suv.h5"); rc=$?
if [ $rc -eq 0 ] && [ "$(echo "$out" | grep '^| ')" = "$(echo "$out2" | grep '^| ')" ]; then
  ok protocol_table_option
else
  ko protocol_table_option "rc=$rc: --table and table: beside give different tables"
fi
if have_h5py; then
  echo "$out" >"$tmp/prot.md"
  chk=$($PY - "$tmp/prot.h5" "$DATA" "$tmp/prot.md" <<'EOF'
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], "r")
s = f["midsize_suv/summary"]
cyc = ["udds", "hwfet", "us06", "wltc3"]
assert [c.decode() if isinstance(c, bytes) else c for c in s["cycles"][:]] == cyc + ["ALL"]
assert s["rel_diff"].shape == (5, 7) and s["fuel_g_tabulated"].shape == (5, 7)
e, t, rel = s["fuel_g_circles_polynomial"][:], s["fuel_g_tabulated"][:], s["rel_diff"][:]
assert abs(e[4] - e[:4].sum(axis=0)).max() < 1e-9 and abs(rel[:4] - (e[:4] - t[:4]) / t[:4]).max() < 1e-15
# The paper's ALL row: the per-cycle rows weighted by each cycle's duration, read here from the CSV files.
dur = np.array([np.loadtxt("%s/cycles/%s.csv" % (sys.argv[2], c), delimiter=",", skiprows=1)[[0, -1], 0] @ [-1, 1]
                for c in cyc])
assert abs(rel[4] - (dur[:, None] * rel[:4]).sum(axis=0) / dur.sum()).max() < 1e-15, rel[4]
assert abs(s["rel_diff_total"][:] - (e[4] - t[4]) / t[4]).max() < 1e-15
assert abs(rel[4] - s["rel_diff_total"][:]).max() > 1e-6  # the two rules differ: the test can tell them apart
# The printed ALL rows are these values.
md = {l.split("|")[2].strip(): [float(x.replace("%", "")) for x in l.split("|")[3:-1]]
      for l in open(sys.argv[3]) if l.startswith("| ALL | rel. diff")}
assert np.allclose(md["rel. diff, duration-weighted mean (paper)"], 100 * rel[4], atol=6e-4)
assert np.allclose(md["rel. diff, total fuel over total fuel"], 100 * s["rel_diff_total"][:], atol=6e-4)
n = sum(1 for c in cyc for g in f["midsize_suv"][c] for m in f["midsize_suv"][c][g])
assert n == 4 * 7 * 2, n
g = f["midsize_suv/udds/theta_+0.0100/tabulated"]
assert g.attrs["project"] == 0 and "fuel_gps" not in g and g["n_samples"][()] > 0
print("ok")
EOF
)
  if [ "$chk" = ok ]; then ok protocol_hdf5; else ko protocol_hdf5 "$chk"; fi
fi

# ---- projection in the protocol: on for every model unless --no-project (the release's script projects) -------
on=$($BIN cycle --protocol --class midsize_suv --cycles "$DATA")
if echo "$on" | grep -q 'Projection: on for every model' \
   && echo "$out" | grep -q 'Projection: off for every model (--no-project)'; then
  single=$($BIN cycle --class midsize_suv --project --grade 0.03 us06 | awk '$1 == "circles_polynomial" { printf "%.2f", $3 }')
  prot=$(echo "$on" | awk -F'|' '$2 == " us06 " && $3 == " circles_polynomial " { gsub(/ /, "", $10); print $10 }')
  if [ -n "$single" ] && [ "$single" = "$prot" ]; then ok protocol_projects; else ko protocol_projects "$single vs $prot"; fi
else
  ko protocol_projects "projection lines missing"
fi

# ---- the release and spline schemes against an independent implementation (tests/cycle_schemes_check.py) -------
if have_h5py && $PY -c 'import scipy, yaml' 2>/dev/null; then
  $PY "$(dirname "$0")/cycle_schemes_check.py" "$BIN" "$DATA" "$(dirname "$0")/../vehicles" "$tmp" 2>&1 \
    | sed 's/^Traceback/FAIL cycle_schemes_check: Traceback/'
else
  echo "SKIP cycle_schemes_check: no h5py, scipy or yaml"
fi

# ---- command-line errors -----------------------------------------------------------------------------------------
printf 'time_s,speed_mps\n0,1\n2000000,1\n' >"$tmp/long.csv"  # 2e8 samples at 100 Hz: refused
bad=""
for args in "--protocol --grade 0.01" "--class midsize_suv --table nope udds" "--class midsize_suv --table x=y.h5 udds" \
            "--class midsize_suv udds hwfet" "udds" "--class midsize_suv --grade abc udds" "--protocol udds" \
            "--class midsize_suv --table midsize_suv=$tmp/none.h5 udds" "--class midsize_suv --scheme central udds" \
            "--class midsize_suv $tmp/long.csv"; do
  $BIN cycle $args >/dev/null 2>"$tmp/err"; rc=$?
  [ $rc -eq 2 ] && [ -s "$tmp/err" ] || bad="$bad [$args: rc=$rc]"
done
if [ -z "$bad" ]; then ok cli_errors; else ko cli_errors "$bad"; fi
