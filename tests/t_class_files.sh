#!/usr/bin/env bash
# Class files. 1) Energy coefficients that break the CIRCLES model's structure are refused when a class loads. The paper
# (Khoudari et al., arXiv:2310.06297) fits c0..c3, p0..p2, q0, q1, z0..z2 and the lower bound h0, h1 by
# non-negative least squares, and f_idle and beta are fuel rates: each must be >= 0. A negative one gives
# negative fuel (f_idle: -5 ran a ring at -72 L/100 km). For every such key, in a light-duty (midsize_sedan)
# or heavy-duty (class8_tractor) class file, `wavefuel energy`, `cycle` and `run` (each loads the class) must
# exit 2 with a message naming the file, line, key and value, and write nothing. Zero stays accepted (shipped
# classes have c2: 0, q0: 0, z2: 0, h0: 0), and so do the coefficients that are negative by design (a0..a4).
# 2) `energy --list` shows both masses where a class carries two (docs/energy.md, "Two masses").
# 3) A run with both masses of its classes changed gives the same fuel, bit for bit.
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
ROOT=$PWD
case "$BIN" in /*) ;; *) BIN="$ROOT/$BIN" ;; esac
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cd "$tmp" || exit 1
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

printf 'v,a,theta\n10,0.5,0\n' > points.csv
printf 'time_s,speed_mps\n0,0\n1,2\n2,4\n3,4\n' > trace.csv
# A small ring whose only class is the file under test.
ring() {
  cat > "$1" <<EOF
name: coef_ring
seed: 1
road: {length_m: 230}
time: {duration_s: 2, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 0}
fleet:
  vehicles: 10
  classes: [{class: ./$2, fraction: 1.0}]
  drivers: [{model: idm, fraction: 1.0}]
EOF
}

# refuse NAME FILE KEY VALUE: all three commands refuse FILE, naming it, the key and the value.
refuse() {
  local name=$1 file=$2 key=$3 val=$4 line msg rc bad=""
  line=$(grep -n "^  $key:" "$file" | cut -d: -f1)
  local want="$file:$line: energy.$key: expected a number in [0, " got="(got '$val')"
  msg=$("$BIN" energy --class "$file" points.csv 2>&1 >e.out); rc=$?
  { [ $rc -eq 2 ] && [ ! -s e.out ] && [[ $msg == *"$want"* ]] && [[ $msg == *"$got"* ]]; } || bad+=" energy(rc=$rc: $msg)"
  msg=$("$BIN" cycle --class "$file" -o c.h5 trace.csv 2>&1 >/dev/null); rc=$?
  { [ $rc -eq 2 ] && [ ! -e c.h5 ] && [ ! -e c.h5.partial ] && [[ $msg == *"$want"* ]] && [[ $msg == *"$got"* ]]; } ||
    bad+=" cycle(rc=$rc: $msg)"
  ring "ring_$name.yaml" "$file"
  msg=$("$BIN" run "ring_$name.yaml" -o r.h5 -q 2>&1 </dev/null); rc=$?
  { [ $rc -eq 2 ] && [ ! -e r.h5 ] && [ ! -e r.h5.partial ] && [[ $msg == *"$want"* ]] && [[ $msg == *"$got"* ]]; } ||
    bad+=" run(rc=$rc: $msg)"
  rm -f e.out
  if [ -z "$bad" ]; then ok "refuse_negative_$name"; else ko "refuse_negative_$name" "$bad"; fi
}

# set_key SRC KEY VALUE OUT: a copy of class SRC with energy.KEY replaced.
set_key() { sed "s/^  $2: [^ ]*/  $2: $3/" "$ROOT/vehicles/$1.yaml" > "$4"; grep -q "^  $2: $3" "$4"; }

n=0
for key in f_idle c0 c1 c2 c3 p0 p1 p2 q0 q1 z0 z1 z2 beta h0 h1; do
  case $key in h0|h1) cls=class8_tractor ;; *) cls=midsize_sedan ;; esac
  # A large value and one just below zero (the bound is 0 itself, not a tolerance).
  for val in -100 -1e-9; do
    f="neg_${key}_${val#-}.yaml"
    if ! set_key $cls $key "$val" "$f"; then ko "refuse_negative_${key}" "could not edit $key in $cls"; continue; fi
    refuse "${key}_${val}" "$f" "$key" "$val"
    n=$((n + 1))
  done
done
[ $n -eq 32 ] && ok "refuse_negative_cases ($n)" || ko "refuse_negative_cases" "$n cases, want 32"

# Zero is accepted for every such key, and the fuel-cut coefficients a0..a4 stay free to be negative (every
# shipped light-duty class has them below 0).
bad=""
for key in f_idle c0 c1 c2 c3 p0 p1 p2 q0 q1 z0 z1 z2 beta h0 h1; do
  case $key in h0|h1) cls=class8_tractor ;; *) cls=midsize_sedan ;; esac
  set_key $cls $key 0 "zero_$key.yaml" || { bad+=" edit($key)"; continue; }
  "$BIN" energy --class "zero_$key.yaml" points.csv >/dev/null 2>&1 || bad+=" $key"
done
[ -z "$bad" ] && ok "zero_coefficients_accepted" || ko "zero_coefficients_accepted" "refused:$bad"
for c in compact_sedan midsize_sedan midsize_suv midsize_pickup; do
  grep -q '^  a0: -' "$ROOT/vehicles/$c.yaml" || bad+=" $c(a0 not negative)"
  "$BIN" energy --class "$c" points.csv >/dev/null 2>&1 || bad+=" $c"
done
[ -z "$bad" ] && ok "negative_fuel_cut_coefficients_accepted" || ko "negative_fuel_cut_coefficients_accepted" "$bad"

# 2) Both masses: `energy --list` shows the release header's and, where the class gives it, the paper's.
list=$("$BIN" energy --list 2>&1); bad=""
for row in "compact_sedan 1543 1379" "class4_pnd 5943 6842" "midsize_sedan 1743 -" "class8_tractor 25104 -"; do
  set -- $row
  echo "$list" | awk -v c="$1" -v m="$2" -v p="$3" '$1 == c && $4 == m && $5 == p { f = 1 } END { exit !f }' || bad+=" $1"
done
head=$(echo "$list" | head -1 | awk '{print $4, $5}')
[ -z "$bad" ] && [ "$head" = "mass_kg paper_mass_kg" ] && ok "list_both_masses" || ko "list_both_masses" "rows:$bad head '$head'"

# 3) Mass enters no fuel value, in a run: tests/data/tiny_ring.yaml with its two classes replaced by copies whose
#    mass_kg is tripled and paper_mass_kg set gives every fuel dataset bit for bit as with the shipped classes.
mkdir mass
sed 's/^mass_kg: 1743/mass_kg: 5229/' "$ROOT/vehicles/midsize_sedan.yaml" > mass/heavy_sedan.yaml
printf 'paper_mass_kg: 4321\n' >> mass/heavy_sedan.yaml
sed 's/^mass_kg: [0-9]*/mass_kg: 77777/' "$ROOT/vehicles/class8_tractor.yaml" > mass/heavy_c8.yaml
scen="$ROOT/tests/data/tiny_ring.yaml"
"$BIN" run "$scen" -q -o ship.h5 >/dev/null 2>&1; rc1=$?
"$BIN" run "$scen" -q -o mass.h5 --set "fleet.classes[0].class=$tmp/mass/heavy_sedan.yaml" \
  --set "fleet.classes[1].class=$tmp/mass/heavy_c8.yaml" >/dev/null 2>&1; rc2=$?
m1=$(WAVEFUEL_VEHICLES="$tmp/mass" "$BIN" energy --list 2>&1 | awk '$1 == "heavy_sedan" { print $4, $5 }')
if [ $rc1 -eq 0 ] && [ $rc2 -eq 0 ] && [ "$m1" = "5229 4321" ] && /usr/bin/python3 - ship.h5 mass.h5 <<'PY'
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
for d in ["timeseries/fuel_rate", "timeseries/class_fuel_rate", "trajectories/fuel_rate", "summary/fuel",
          "summary/class_fuel", "summary/l_per_100km", "summary/class_l_per_100km"]:
    x, y = a[d][()], b[d][()]
    assert np.asarray(x).tobytes() == np.asarray(y).tobytes(), d
PY
then ok "mass_enters_no_fuel_in_a_run"; else ko "mass_enters_no_fuel_in_a_run" "rc=$rc1/$rc2 masses '$m1'"; fi
