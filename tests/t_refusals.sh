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
# Energy rows: name | the CSV (printf format) | the message after "e_NAME.csv:".
while IFS='|' read -r name text want; do
  printf "$text" > "e_$name.csv"
  refuse "energy_$name" "e_$name.csv:$want" -- "$BIN" energy --class midsize_sedan "e_$name.csv"
done <<'T'
speed_out_of_range|v,a,theta\n10,0,0\n1e308,0,0\n|3: field 1 (v) must be in [0, 150] m/s (got 1e+308)
grade_out_of_range|10,0,100000\n|1: field 3 (theta) must be in [-0.5, 0.5] rad (got 100000)
accel_out_of_range|10,-25,0\n|1: field 2 (a) must be in [-20, 20] m/s^2 (got -25)
negative_speed|10,0,0\n-0.5,0,0\n|2: field 1 (v) must be in [0, 150] m/s (got -0.5)
hex_first_row|0x10,0,0\n|1: field 1 (v): expected a finite number (got '0x10')
hex_float|v,a,theta\n10,0x1p-2,0\n|2: field 2 (a): expected a finite number (got '0x1p-2')
T
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

cp "$REPO/tests/data/tiny_ring.yaml" s.yaml   # name: tiny; line 5 road.length_m; trajectories on
sed 's/length_m: 230/length_m: 0xE6/' s.yaml > s_hex.yaml
refuse yaml_hex "s_hex.yaml:5: road.length_m: expected a number" -- "$BIN" run s_hex.yaml -o s_hex.h5 -q
refuse set_hex "--set: time.duration_s: expected a number" -- "$BIN" run s.yaml --set time.duration_s=0x2 -o x.h5 -q
refuse option_hex "--threads expects an integer" -- "$BIN" run s.yaml --threads 0x2 -o x.h5 -q
# Safety filters (docs/controllers.md#safety-filters): kind, values and keys of fleet.drivers[i].safety. Rows: name |
# the group's safety map | the message after "sf_NAME.yaml:17: ".
while IFS='|' read -r name map want; do
  sed "s/noise_mps2: 0.3}/noise_mps2: 0.3, safety: $map}/" s.yaml > "sf_$name.yaml"
  refuse "safety_$name" "sf_$name.yaml:17: $want" -- "$BIN" run "sf_$name.yaml" -o sf.h5 -q
  rm -f "sf_$name.yaml"
done <<'T'
unknown_kind|{kind: gips}|fleet.drivers[0].safety.kind: unknown safety filter kind 'gips' (known: gipps, ttc)
bad_value|{kind: gipps, decel_mps2: 0.2}|fleet.drivers[0].safety.decel_mps2: expected a number in [0.5, 20] m/s^2 (got '0.2')
unknown_key|{kind: ttc, ttc: 3}|unknown key 'fleet.drivers[0].safety.ttc' (did you mean 'ttc_s'?)
missing_kind|{ttc_s: 3}|fleet.drivers[0].safety: missing 'kind': the safety filter (gipps, ttc)
T
refuse safety_set_value "--set: fleet.drivers[0].safety.ttc_s: expected a number in [0.1, 20] s (got '-1')" -- \
  "$BIN" run s.yaml --set 'fleet.drivers[0].safety.kind=ttc' --set 'fleet.drivers[0].safety.ttc_s=-1' -o sf.h5 -q

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
sed 's|^name: tiny$|name: "a/b"|' s.yaml > name_slash.yaml
refuse name_with_slash "name_slash.yaml:2: name 'a/b' contains '/'" -- "$BIN" run name_slash.yaml -q
sed 's|^name: tiny$|name: ".."|' s.yaml > name_dots.yaml
refuse name_dotdot "name_dots.yaml:2: name '..' is '.' or '..'" -- "$BIN" run name_dots.yaml -q
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
LONG=(--set time.duration_s=3000 --set time.integrator=euler --set fleet.vehicles=400 --set road.length_m=8000
      --set output.trajectories=false --set time.warmup_s=0)
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

# ---------------------------------------------------------------- every command: help, -V, unknown options, repeats
version=$("$BIN" --version)
cmds=$("$BIN" --help | awk '/^  [a-z]+ / { print $1 }')
[ "$(echo "$cmds" | wc -l)" -ge 7 ] || ko command_list "from wavefuel --help: $cmds"
for c in $cmds; do
  h1=$("$BIN" help "$c" 2>&1); rc1=$?; h2=$("$BIN" "$c" --help 2>&1); rc2=$?
  if [ $rc1 -eq 0 ] && [ "$h1" = "$h2" ] && echo "$h1" | grep -q "usage: wavefuel $c"; then ok "help_$c"
  else ko "help_$c" "rc=$rc1/$rc2"; fi
  v=$("$BIN" "$c" -V 2>&1); rc=$?
  if [ $rc -eq 0 ] && [ "$v" = "$version" ]; then ok "version_$c"; else ko "version_$c" "rc=$rc '$v'"; fi
  refuse "unknown_option_$c" "wavefuel $c: unknown option '--no-such-option' (options: wavefuel help $c)" -- \
    "$BIN" "$c" --no-such-option
done
for a in import info sample; do
  v=$("$BIN" table "$a" -V 2>&1); rc=$?
  if [ $rc -eq 0 ] && [ "$v" = "$version" ]; then ok "version_table_$a"; else ko "version_table_$a" "rc=$rc '$v'"; fi
  h1=$("$BIN" help table "$a"); h2=$("$BIN" table "$a" --help)
  if [ -n "$h1" ] && [ "$h1" = "$h2" ]; then ok "help_table_$a"; else ko "help_table_$a" "differs"; fi
done
refuse output_twice_run "wavefuel run: given twice: -o/--output" -- "$BIN" run s.yaml -o a.h5 -o b.h5 -q
refuse output_twice_sweep "wavefuel sweep: given twice: -o/--output" -- "$BIN" sweep sw.yaml -o a.h5 --output b.h5
refuse output_twice_cycle "wavefuel cycle: given twice: -o/--output" -- \
  "$BIN" cycle --class midsize_sedan -o a.h5 -o b.h5 cyc.csv
refuse output_twice_table "wavefuel table import: given twice: -o/--output" -- "$BIN" table import tab.csv -o a.h5 -o b.h5
refuse output_twice_fit "wavefuel fit: given twice: -o/--output" -- "$BIN" fit tab.csv -o a.yaml -o b.yaml
refuse class_twice_energy "wavefuel energy: given twice: -c/--class" -- \
  "$BIN" energy --class midsize_sedan --class compact_sedan e_edges.csv
refuse project_conflict "wavefuel cycle: options that exclude each other: --project and --no-project" -- \
  "$BIN" cycle --class midsize_sedan --project --no-project cyc.csv
refuse missing_value "wavefuel run: a value is needed after -o/--output" -- "$BIN" run s.yaml -o
# Options that may repeat still do.
if "$BIN" run s.yaml --set seed=4 --set seed=5 -q -o twice.h5 && [ -f twice.h5 ]; then ok set_repeats
else ko set_repeats "rc=$?"; fi

# ---------------------------------------------------------------- info: what kind of file
"$BIN" sweep sw.yaml -o sw_table.h5 -q
"$BIN" cycle --class midsize_sedan -o cyc_result.h5 cyc.csv >/dev/null
refuse info_missing "wavefuel: nothing.h5: no such file" -- "$BIN" info nothing.h5
refuse info_directory "wavefuel: outdir: is a directory, not a wavefuel result" -- "$BIN" info outdir
refuse info_not_hdf5 "wavefuel: garbage.h5: is not an HDF5 file (or a damaged one), not a wavefuel result" -- \
  "$BIN" info garbage.h5
refuse info_table "table.h5: is a wavefuel energy table: \`wavefuel table info table.h5\` describes it" -- \
  "$BIN" info table.h5
out=$("$BIN" info sw_table.h5); rc=$?
if [ $rc -eq 0 ] && echo "$out" | grep -q "^sw_table.h5: a wavefuel sweep table" &&
   echo "$out" | grep -qE "^  runs_ok +2 *$"; then ok info_shows_sweep_table; else ko info_shows_sweep_table "rc=$rc $out"; fi
out=$("$BIN" info cyc_result.h5); rc=$?
fuel=$("$BIN" cycle --class midsize_sedan cyc.csv | awk '$1 == "circles_polynomial" { print $3 }')
shown=$(echo "$out" | awk '$1 == "fuel_g" { print $2 }')
if [ $rc -eq 0 ] && echo "$out" | grep -q "drive-cycle result" &&
   awk -v a="$fuel" -v b="$shown" 'BEGIN { exit !(a != "" && (a - b < 1e-3 && b - a < 1e-3)) }'; then
  ok info_shows_cycle_result; else ko info_shows_cycle_result "rc=$rc fuel $fuel shown $shown: $out"; fi

# ---------------------------------------------------------------- SUNDIALS' own messages land in wavefuel's
msg=$("$BIN" run s.yaml -q -o cv.h5 --set time.integrator=cvode --set solver.max_steps=1 2>&1); rc=$?
if [ $rc -eq 1 ] && echo "$msg" | grep -q "^wavefuel: SUNDIALS: CVode failed .*: CVODES error in CVode: .*mxstep" &&
   ! echo "$msg" | grep -q '^\[CVODES'; then ok sundials_message_captured; else ko sundials_message_captured "$msg"; fi
refuse arkode_unknown_table "solver.method: unknown ARKODE explicit table 'ARKODE_NO_SUCH' (known: ARKODE_HEUN_EULER_2_1_2" -- \
  "$BIN" run s.yaml -q -o ark.h5 --set time.integrator=arkode --set solver.method=ARKODE_NO_SUCH
msg=$("$BIN" run s.yaml -q -o ark.h5 --set time.integrator=arkode --set solver.method=ARKODE_NO_SUCH 2>&1)
if ! echo "$msg" | grep -q 'ARKODE ERROR'; then ok arkode_prints_nothing_itself; else ko arkode_prints_nothing_itself "$msg"; fi

# ---------------------------------------------------------------- fit -o: not over its table or its --like class
"$BIN" table sample --class midsize_sedan -o fit_in.csv >/dev/null
refuse fit_output_is_table "-o fit_in.csv: is the input fit_in.csv" -- "$BIN" fit fit_in.csv --like midsize_sedan -o fit_in.csv --force
refuse fit_output_is_like_class "-o cls/my_sedan.yaml: is the input" -- \
  "$BIN" fit fit_in.csv --like cls/my_sedan.yaml -o cls/my_sedan.yaml --force
refuse fit_output_is_directory "-o outdir: is a directory" -- "$BIN" fit fit_in.csv --like midsize_sedan -o outdir
