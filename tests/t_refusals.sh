#!/usr/bin/env bash
# Inputs that wavefuel used to accept and must refuse (issue 19, section 2): out-of-range and non-decimal numbers in
# CSV rows, YAML values and options; outputs that are an input or a directory; scenario names that are not a plain
# file name; sweep override keys. Each refusal must exit with status 2, print a message containing the expected
# text (file, row, key and value) and touch no file (inputs unchanged, no result or partial file left).
# Prints "PASS name" / "FAIL name: why".
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
REPO=$PWD
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir "$tmp/w" && cd "$tmp/w" || exit 1
case "$BIN" in /*) ;; *) BIN="$OLDPWD/$BIN" ;; esac
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

# Every path under the working directory with the checksum of each file.
snapshot() { { find . ! -type f; find . -type f -exec cksum {} +; } | sort; }
# refuse NAME WANT -- COMMAND...: COMMAND must exit 2 with every @@-separated part of WANT in its stderr, print
# nothing on stdout, and leave the directory's listing and every file's bytes as they were.
refuse() {
  local name=$1 want=$2; shift 3
  local before after msg rc part rest=$want@@
  before=$(snapshot)
  msg=$("$@" 2>&1 >"$tmp/stdout" </dev/null); rc=$?
  after=$(snapshot)
  if [ -s "$tmp/stdout" ]; then ko "$name" "printed on stdout: $(head -c 200 "$tmp/stdout")"; return; fi
  if [ "$rc" -ne 2 ]; then ko "$name" "rc=$rc (want 2): $msg"; return; fi
  if [ "$before" != "$after" ]; then ko "$name" "files changed: $(diff <(echo "$before") <(echo "$after") | head -5)"
    return; fi
  while [ -n "$rest" ]; do
    part=${rest%%@@*} rest=${rest#*@@}
    printf '%s' "$msg" | grep -qF -- "$part" || { ko "$name" "want '$part', got: $msg"; return; }
  done
  ok "$name"; [ -n "${SHOW_MSG:-}" ] && echo "    $msg"
  return 0
}

# ---------------------------------------------------------------- numbers: ranges and decimal notation
printf 'v,a,theta\n10,0,0\n1e308,0,0\n' > e_huge_v.csv
refuse energy_speed_out_of_range "e_huge_v.csv:3: field 1 (v) must be in [0, 150] m/s (got 1e+308)" -- \
  "$BIN" energy --class midsize_sedan e_huge_v.csv
printf '10,0,100000\n' > e_grade.csv
refuse energy_grade_out_of_range "e_grade.csv:1: field 3 (theta) must be in [-0.5, 0.5] rad (got 100000)" -- \
  "$BIN" energy --class midsize_sedan e_grade.csv
printf '10,-25,0\n' > e_accel.csv
refuse energy_accel_out_of_range "e_accel.csv:1: field 2 (a) must be in [-20, 20] m/s^2 (got -25)" -- \
  "$BIN" energy --class midsize_sedan e_accel.csv
printf '10,0,0\n-0.5,0,0\n' > e_neg.csv
refuse energy_negative_speed "e_neg.csv:2: field 1 (v) must be in [0, 150] m/s (got -0.5)" -- \
  "$BIN" energy --class midsize_sedan e_neg.csv
printf '0x10,0,0\n' > e_hex.csv
refuse energy_hex_first_row "e_hex.csv:1: field 1 (v): expected a finite number (got '0x10')" -- \
  "$BIN" energy --class midsize_sedan e_hex.csv
printf 'v,a,theta\n10,0x1p-2,0\n' > e_hex2.csv
refuse energy_hex_float "e_hex2.csv:2: field 2 (a): expected a finite number (got '0x1p-2')" -- \
  "$BIN" energy --class midsize_sedan e_hex2.csv
# The bounds themselves are accepted (inclusive), and 0.3 is still 0.3.
printf '150,20,0.5\n0,-20,-0.5\n' > e_edges.csv
if out=$("$BIN" energy --class midsize_sedan e_edges.csv) && [ "$(echo "$out" | wc -l)" -eq 3 ]; then
  ok energy_bounds_inclusive; else ko energy_bounds_inclusive "$out"; fi

printf 'time_s,speed_mps\n0,0\n0x1,1\n2,0\n' > c_hex.csv
refuse cycle_hex_time "c_hex.csv:3: field 1 (time_s): expected a finite number (got '0x1')" -- \
  "$BIN" cycle --class midsize_sedan -o c_hex.h5 c_hex.csv
printf 'time_s,speed_mps\n0,0\n1,150.5\n2,0\n' > c_fast.csv
refuse cycle_speed_out_of_range "c_fast.csv:3: field 2 (speed_mps) must be in [0, 150] m/s (got 150.5)" -- \
  "$BIN" cycle --class midsize_sedan -o c_fast.h5 c_fast.csv
printf 'time_s,speed_mps\n0,0\n1,1\n2,0\n' > c_ok.csv
refuse cycle_grade_hex "--grade expects a road grade angle in [-0.5, 0.5] rad (got '0x0')" -- \
  "$BIN" cycle --class midsize_sedan --grade 0x0 c_ok.csv
refuse cycle_grade_out_of_range "--grade expects a road grade angle in [-0.5, 0.5] rad (got '0.6')" -- \
  "$BIN" cycle --class midsize_sedan --grade 0.6 c_ok.csv

cat > s.yaml <<'Y'
name: s
seed: 3
road:
  length_m: 230
time:
  duration_s: 2
  dt_s: 0.1
fleet:
  vehicles: 22
  classes:
    - {class: midsize_sedan, fraction: 1.0}
  drivers:
    - {model: idm, fraction: 1.0}
Y
sed 's/length_m: 230/length_m: 0xE6/' s.yaml > s_hex.yaml
refuse yaml_hex "s_hex.yaml:4: road.length_m: expected a number" -- "$BIN" run s_hex.yaml -o s_hex.h5 -q
refuse set_hex "--set: time.duration_s: expected a number" -- "$BIN" run s.yaml --set time.duration_s=0x2 -o x.h5 -q
refuse option_hex "--threads expects an integer" -- "$BIN" run s.yaml --threads 0x2 -o x.h5 -q

# ---------------------------------------------------------------- outputs that are inputs or directories
mkdir cls sub
cp "$REPO/vehicles/midsize_sedan.yaml" cls/my_sedan.yaml
printf 'x_m,grade_rad\n0,0\n100,0\n200,0\n' > grade.csv
sed -e 's|class: midsize_sedan|class: cls/my_sedan.yaml|' -e 's|length_m: 230|length_m: 230\n  grade: {csv: grade.csv}|' \
  s.yaml > in.yaml
if "$BIN" run in.yaml -o in_ok.h5 -q && [ -f in_ok.h5 ]; then ok inputs_scenario_runs; rm -f in_ok.h5
else ko inputs_scenario_runs "rc=$?"; fi
refuse run_output_is_scenario "-o in.yaml: is the input in.yaml: refusing to write the result over it" -- \
  "$BIN" run in.yaml -o in.yaml --force -q
refuse run_output_path_key_is_scenario "output.path in.yaml: is the input in.yaml" -- \
  "$BIN" run in.yaml --set output.path=in.yaml --force -q
refuse run_output_other_spelling "-o sub/../in.yaml: is the input in.yaml" -- \
  "$BIN" run in.yaml -o sub/../in.yaml --force -q
ln -s in.yaml link.yaml
refuse run_output_symlink "-o link.yaml: is the input in.yaml" -- "$BIN" run in.yaml -o link.yaml --force -q
refuse run_output_is_class "-o cls/my_sedan.yaml: is the input cls/my_sedan.yaml" -- \
  "$BIN" run in.yaml -o cls/my_sedan.yaml --force -q
refuse run_output_is_grade_csv "-o grade.csv: is the input grade.csv" -- "$BIN" run in.yaml -o grade.csv --force -q
cp in.yaml side.yaml
refuse run_partial_is_input "-o side: side.partial, written beside the result, is the input side.partial" -- \
  "$BIN" run "$(cp in.yaml side.partial; echo side.partial)" -o side --force -q
rm -f side.yaml side.partial
# A directory is refused before the run starts: no DIR.partial, and at once even for a long run.
mkdir outdir
start=$SECONDS
refuse run_output_is_directory "-o outdir: is a directory; give a file name (outdir/NAME.h5)" -- \
  "$BIN" run in.yaml -o outdir --set time.duration_s=100000 -q
if [ $((SECONDS - start)) -le 5 ]; then ok run_directory_refused_before_running
else ko run_directory_refused_before_running "took $((SECONDS - start)) s"; fi

printf 'time_s,speed_mps\n0,0\n1,1\n2,0\n' > cyc.csv
refuse cycle_output_is_cycle "-o cyc.csv: is the input cyc.csv" -- \
  "$BIN" cycle --class midsize_sedan -o cyc.csv --force cyc.csv
refuse cycle_output_is_class "-o cls/my_sedan.yaml: is the input cls/my_sedan.yaml" -- \
  "$BIN" cycle --class cls/my_sedan.yaml -o cls/my_sedan.yaml --force cyc.csv
refuse cycle_output_is_directory "-o outdir: is a directory" -- "$BIN" cycle --class midsize_sedan -o outdir cyc.csv
refuse protocol_output_is_class "-o cls/my_sedan.yaml: is the input cls/my_sedan.yaml" -- \
  "$BIN" cycle --protocol --class cls/my_sedan.yaml -o cls/my_sedan.yaml --force
printf 'Velocity,Acceleration,Road Grade,Fuel Rate,Infeasible\n0,0,0,0.1,0\n' > tab.csv
refuse table_import_output_is_input "-o tab.csv: is the input tab.csv" -- "$BIN" table import tab.csv -o tab.csv --force
refuse table_import_output_is_directory "-o outdir: is a directory" -- "$BIN" table import tab.csv -o outdir
refuse table_sample_output_is_class "-o cls/my_sedan.yaml: is the input cls/my_sedan.yaml" -- \
  "$BIN" table sample --class cls/my_sedan.yaml -o cls/my_sedan.yaml --force

# ---------------------------------------------------------------- sweeps
cat > sw.yaml <<'Y'
name: sw
scenario: in.yaml
axes:
  - {key: fleet.vehicles, values: [20, 22]}
Y
refuse sweep_output_is_sweep "-o sw.yaml: is the input sw.yaml" -- "$BIN" sweep sw.yaml -o sw.yaml --force -q
refuse sweep_output_is_scenario "-o in.yaml: is the input" -- "$BIN" sweep sw.yaml -o in.yaml --force -q
refuse sweep_output_is_class "-o cls/my_sedan.yaml: is the input cls/my_sedan.yaml" -- \
  "$BIN" sweep sw.yaml -o cls/my_sedan.yaml --force -q
refuse sweep_output_is_directory "-o outdir: is a directory" -- "$BIN" sweep sw.yaml -o outdir -q
sed 's/fleet.vehicles/fleet.vehicls/' sw.yaml > sw_typo.yaml
refuse sweep_misspelled_key "sw_typo.yaml: run 0: --set: unknown key 'fleet.vehicls' (did you mean 'vehicles'?)" -- \
  "$BIN" sweep sw_typo.yaml -o sw_typo.h5 -q
refuse sweep_misspelled_key_list "unknown key 'fleet.vehicls'" -- "$BIN" sweep sw_typo.yaml --list
# A key misspelled only in the second of two explicit runs, after a first run with a bad value: still found.
cat > sw_runs.yaml <<'Y'
name: swr
scenario: in.yaml
runs:
  - {fleet.vehicles: 0}
  - {time.duraton_s: 3}
Y
refuse sweep_misspelled_key_second_run "sw_runs.yaml: run 1: --set: unknown key 'time.duraton_s'" -- \
  "$BIN" sweep sw_runs.yaml -o sw_runs.h5 -q
# A bad value (not a key) still fails its run alone: the sweep runs the others and exits 1.
sed 's/values: \[20, 22\]/values: [0, 22]/' sw.yaml > sw_value.yaml
"$BIN" sweep sw_value.yaml -o sw_value.h5 -q 2>/dev/null; rc=$?
if [ $rc -eq 1 ] && [ -f sw_value.h5 ]; then ok sweep_bad_value_fails_alone; else ko sweep_bad_value_fails_alone "rc=$rc"; fi

# ---------------------------------------------------------------- names: a plain file name that fits, never cut
refuse name_escapes_output "--set: name '../escape' contains '/'" -- "$BIN" run s.yaml --set name=../escape -q
sed 's|^name: s$|name: "a/b"|' s.yaml > name_slash.yaml
refuse name_with_slash "name_slash.yaml:1: name 'a/b' contains '/'" -- "$BIN" run name_slash.yaml -q
sed 's|^name: s$|name: ".."|' s.yaml > name_dots.yaml
refuse name_dotdot "name_dots.yaml:1: name '..' is '.' or '..'" -- "$BIN" run name_dots.yaml -q
long=$(printf 'n%.0s' $(seq 128))
refuse name_too_long "--set: name '$long' is too long (128 bytes; at most 127)" -- "$BIN" run s.yaml --set "name=$long" -q
grep -v '^name:' s.yaml > "$long.yaml"
refuse name_stem_too_long "$long.yaml: the file's stem '$long', the default name, is too long (128 bytes; at most 127): set \`name:\`" -- \
  "$BIN" run "$long.yaml" -q
rm -f "$long.yaml"
# 127 bytes is the limit, not a cut: the result is output/NAME.h5 with all 127 characters.
ok127=$(printf 'k%.0s' $(seq 127))
mkdir -p output
if "$BIN" run s.yaml --set "name=$ok127" -q && [ -f "output/$ok127.h5" ]; then ok name_127_bytes_kept
else ko name_127_bytes_kept "no output/$ok127.h5"; fi
rm -rf output
longpath=$(printf 'p%.0s' $(seq 1100))
refuse output_path_too_long "--set: output.path: too long (1100 bytes; at most 1023)" -- \
  "$BIN" run s.yaml --set "output.path=$longpath" -q
printf 'name: ../x\nscenario: s.yaml\naxes:\n  - {key: fleet.vehicles, values: [20]}\n' > sw_name.yaml
refuse sweep_name_with_slash "sw_name.yaml:1: name '../x' contains '/'" -- "$BIN" sweep sw_name.yaml -q

# ---------------------------------------------------------------- --resume: X.h5, X.h5.partial or X.h5.ckpt
. "$REPO/tests/interrupt.sh"
pids=()
trap 'for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done; rm -rf "$tmp"' EXIT
"$BIN" run s.yaml -q -o done.h5
LONG=(--set time.duration_s=3000 --set time.integrator=euler --set fleet.vehicles=400 --set road.length_m=8000)
"$BIN" run s.yaml -q -o ref.h5 "${LONG[@]}"
for form in partial ckpt h5; do
  "$BIN" run s.yaml -q -o "r_$form.h5" "${LONG[@]}" \
    --checkpoint-every 0.01 2>/dev/null & pid=$!
  pids+=("$pid")
  if wait_checkpoint "r_$form.h5" $pid && signal_running TERM $pid; then wait $pid; rc1=$?
  else wait $pid; rc1=$?; fi
  arg="r_$form.h5"; [ "$form" = h5 ] || arg="r_$form.h5.$form"
  # The resumed run's time series and summary are those of the uninterrupted run (h5dump's text, after the file name).
  if [ $rc1 -eq 3 ] && "$BIN" run --resume "$arg" -q && [ -f "r_$form.h5" ] && [ ! -e "r_$form.h5.partial" ] &&
     cmp -s <(h5dump -g /timeseries -g /summary ref.h5 | tail -n +2) \
            <(h5dump -g /timeseries -g /summary "r_$form.h5" | tail -n +2) &&
     [ "$(h5dump -g /timeseries ref.h5 | wc -l)" -gt 1000 ]; then
    ok "resume_given_as_$form"
  else ko "resume_given_as_$form" "rc=$rc1 (the run may have ended before its signal)"; fi
  rm -f "r_$form.h5"
done
echo garbage > garbage.h5
refuse resume_garbage "--resume garbage.h5: garbage.h5 is not an HDF5 file (or a damaged one), not a wavefuel partial result or checkpoint" -- \
  "$BIN" run --resume garbage.h5 -q
refuse resume_garbage_partial_form "garbage.h5 is not an HDF5 file" -- "$BIN" run --resume garbage.h5.partial -q
refuse resume_complete "--resume done.h5: done.h5 is complete: nothing to resume" -- "$BIN" run --resume done.h5 -q
refuse resume_complete_ckpt_form "done.h5 is complete: nothing to resume" -- "$BIN" run --resume done.h5.ckpt -q
"$BIN" table sample --class midsize_sedan -o table.h5 >/dev/null
refuse resume_energy_table "table.h5 is a wavefuel energy table, not a wavefuel partial result or checkpoint" -- \
  "$BIN" run --resume table.h5 -q
refuse resume_directory "outdir is a directory, not a wavefuel partial result or checkpoint" -- \
  "$BIN" run --resume outdir -q
refuse resume_missing "--resume none.h5: no such file, and no checkpoint none.h5.ckpt" -- "$BIN" run --resume none.h5 -q
cp done.h5 other.h5.partial
echo garbage > other.h5.ckpt
refuse resume_garbage_checkpoint "other.h5.ckpt is not a readable checkpoint: it is not an HDF5 file" -- \
  "$BIN" run --resume other.h5.partial -q
