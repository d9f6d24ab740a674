#!/usr/bin/env bash
# `wavefuel energy` end to end: help, --list, CSV input with header/comments/blank lines, 17-digit output whose
# values match numbers worked out here with awk from the issue's parameter table, power = fuel * kW per g/s,
# --project, and the input errors that must give exit status 2, a message naming line and field, and no
# output at all. Prints "PASS name" / "FAIL name: why" per case.
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

# --help: exit 0, usage on stdout.
out=$($BIN energy --help); rc=$?
if [ $rc -eq 0 ] && echo "$out" | grep -q 'usage: wavefuel energy --class'; then ok help; else ko help "rc=$rc"; fi

# --list: the six shipped classes with duty and fuel type.
list=$($BIN energy --list); rc=$?
bad=""
for row in "compact_sedan light gasoline" "midsize_sedan light gasoline" "midsize_suv light gasoline" \
           "midsize_pickup light gasoline" "class4_pnd heavy diesel" "class8_tractor heavy diesel"; do
  set -- $row
  echo "$list" | awk -v c="$1" -v d="$2" -v f="$3" '$1 == c && $2 == d && $3 == f { found = 1 } END { exit !found }' \
    || bad="$bad $1"
done
if [ $rc -eq 0 ] && [ -z "$bad" ]; then ok list_six_classes; else ko list_six_classes "rc=$rc missing:$bad"; fi

# A CSV with a header, comments and blank lines.
cat >"$tmp/in.csv" <<'EOF'
# points for the compact sedan
v,a,theta

10,0,0
  # an indented comment
0,0,0
15,5,0.02
20, 0.5 ,-0.01
EOF
out=$($BIN energy --class compact_sedan "$tmp/in.csv"); rc=$?
nrows=$(echo "$out" | tail -n +2 | wc -l)
if [ $rc -eq 0 ] && [ "$(echo "$out" | head -1)" = "v,a,theta,fuel_gps,power_kw,flag" ] && [ "$nrows" -eq 4 ]; then
  ok csv_header_comments_blank
else
  ko csv_header_comments_blank "rc=$rc rows=$nrows"
fi

# The known point: compact_sedan at (10, 0, 0) is c0 + c1*10 + c3*1000 = 0.325699 g/s (a = theta = 0, v above
# v_c, no cut), power 0.325699 * 42.36 kW. Worked out by awk in doubles and printed with 17 digits.
row=$(echo "$out" | sed -n 2p)
want=$(awk 'BEGIN { f = 0.15918 + 0.013463 * 10 + 3.1889e-05 * 10 * 10 * 10; printf "%.17g,%.17g", f, f * 42.36 }')
got=$(echo "$row" | cut -d, -f4,5)
if [ "$got" = "$want" ]; then ok known_point_value; else ko known_point_value "got $got want $want"; fi

# 17 significant digits: %.17g drops trailing zeros, so each field must re-print to itself with %.17g (it
# carries all the digits a double needs) and never exceed 17 digits; and 0.325699 needs all 17.
digits_bad=$(echo "$out" | tail -n +2 | awk -F, '{
  for (i = 1; i <= 5; i++) { s = $i; sub(/^-/, "", s); sub(/[eE].*/, "", s); sub(/\./, "", s); sub(/^0+/, "", s);
    if (length(s) > 17 || sprintf("%.17g", $i + 0) != $i) print NR ": " $i } }')
if [ -z "$digits_bad" ] && echo "$out" | grep -q ',0.32569900000000002,'; then ok seventeen_digits
else ko seventeen_digits "$digits_bad"; fi

# Idle at rest is f_idle; power = fuel * 42.36 exactly on every row (same double product in awk); flags.
row0=$(echo "$out" | sed -n 3p)
if [ "$(echo "$row0" | cut -d, -f4)" = "$(awk 'BEGIN { printf "%.17g", 0.0972 }')" ]; then ok idle_is_f_idle; else ko idle_is_f_idle "$row0"; fi
pw_bad=$(echo "$out" | tail -n +2 | awk -F, '{ p = sprintf("%.17g", $4 * 42.36); if (p != $5) print NR ": " $5 " vs " p }')
if [ -z "$pw_bad" ]; then ok power_is_fuel_times_kw; else ko power_is_fuel_times_kw "$pw_bad"; fi
flags=$(echo "$out" | tail -n +2 | cut -d, -f6 | tr '\n' ' ')
if [ "$flags" = "0 0 1 0 " ]; then ok flags_0_1; else ko flags_0_1 "$flags"; fi

# Standard input and a second run give the same bytes; --project lowers the infeasible row only.
out2=$($BIN energy --class compact_sedan - <"$tmp/in.csv")
if [ "$out" = "$out2" ]; then ok stdin_same_as_file; else ko stdin_same_as_file "outputs differ"; fi
outp=$($BIN energy --class compact_sedan --project "$tmp/in.csv")
cmp=$(paste -d, <(echo "$out" | tail -n +2) <(echo "$outp" | tail -n +2) | awk -F, '{
  if ($6 == 1) { if (!($10 < $4)) print "row " NR " not lowered" }
  else if ($4 != $10) print "row " NR " changed" }')
if [ -z "$cmp" ]; then ok project_clips_infeasible_only; else ko project_clips_infeasible_only "$cmp"; fi

# --class with a path to a YAML file gives the same result as the name.
outf=$($BIN energy --class vehicles/compact_sedan.yaml "$tmp/in.csv"); rc=$?
if [ $rc -eq 0 ] && [ "$outf" = "$out" ]; then ok class_as_path; else ko class_as_path "rc=$rc"; fi
cp vehicles/class8_tractor.yaml "$tmp/my_truck.yaml"
outt=$(echo "10,-3,0" | $BIN energy --class "$tmp/my_truck.yaml"); rc=$?
# h0 + h1 v = 0.49109 + 0.025152 * 10 (the lower bound holds at this hard braking).
want=$(awk 'BEGIN { printf "%.17g", 0.49109 + 0.025152 * 10 }')
if [ $rc -eq 0 ] && [ "$(echo "$outt" | sed -n 2p | cut -d, -f4)" = "$want" ]; then ok class_path_outside_repo
else ko class_path_outside_repo "rc=$rc $outt"; fi

# Errors: exit 2, a message naming what is wrong, nothing at all on stdout.
expect_err() { # name, expected substring, command...
  local name=$1 want=$2; shift 2
  local o e rc
  o=$("$@" 2>"$tmp/err"); rc=$?
  e=$(cat "$tmp/err")
  if [ $rc -eq 2 ] && [ -z "$o" ] && echo "$e" | grep -qF -- "$want"; then ok "$name"
  else ko "$name" "rc=$rc stdout='${o:0:60}' stderr='$e' (want '$want')"; fi
}
printf 'v,a,theta\n1,0,0\n# c\n2,0.5x,0\n' >"$tmp/bad_num.csv"
expect_err bad_number_line_field "bad_num.csv:4: field 2 (a)" $BIN energy --class compact_sedan "$tmp/bad_num.csv"
printf '1,0,0\n2,0,0,7\n' >"$tmp/extra.csv"
expect_err too_many_fields "extra.csv:2: field 4" $BIN energy --class compact_sedan "$tmp/extra.csv"
printf '1,0,0\n\n2,0\n' >"$tmp/short.csv"
expect_err too_few_fields "short.csv:3: 2 fields, expected 3" $BIN energy --class compact_sedan "$tmp/short.csv"
printf '1,0,0\n2,,0\n' >"$tmp/empty.csv"
expect_err empty_field "empty.csv:2: field 2 (a)" $BIN energy --class compact_sedan "$tmp/empty.csv"
printf '1,0,0\n2,0,inf\n' >"$tmp/inf.csv"
expect_err infinite_value "inf.csv:2: field 3 (theta)" $BIN energy --class compact_sedan "$tmp/inf.csv"
printf 'v,acc,theta\n1,0,0\n' >"$tmp/hdr.csv"
expect_err wrong_header "hdr.csv:1: header column 2 is 'acc', expected 'a'" $BIN energy --class compact_sedan "$tmp/hdr.csv"
expect_err missing_input_file "cannot open" $BIN energy --class compact_sedan "$tmp/none.csv"
expect_err missing_class "--class NAME is required" $BIN energy "$tmp/in.csv"
expect_err unknown_class "'no_such_car' not found" $BIN energy --class no_such_car "$tmp/in.csv"
o=$($BIN energy --class no_such_car "$tmp/in.csv" 2>&1)
if echo "$o" | grep -q 'compact_sedan' && echo "$o" | grep -q 'class8_tractor'; then ok unknown_class_lists_known
else ko unknown_class_lists_known "$o"; fi
expect_err two_input_files "one input file at most" $BIN energy --class compact_sedan "$tmp/in.csv" "$tmp/in.csv"
expect_err bad_option "unknown option '--bogus' (options: wavefuel help energy)" $BIN energy --bogus compact_sedan

# The programs' class search path ($WAVEFUEL_VEHICLES, then PREFIX/vehicles for PREFIX/bin/wavefuel;
# docs/energy.md): a class in the user's directory is found and listed, shadows a shipped class of the same name,
# and the shipped classes stay found; the same binary moved to another PREFIX finds that PREFIX's vehicles/.
ROOT=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$tmp/mine" "$tmp/prefix/bin" "$tmp/prefix/vehicles"
sed 's/^name:.*/name: My Van/' "$ROOT/vehicles/midsize_suv.yaml" >"$tmp/mine/my_van.yaml"
sed 's/^name:.*/name: Heavier SUV/' "$ROOT/vehicles/midsize_suv.yaml" >"$tmp/mine/midsize_suv.yaml"
l=$(WAVEFUEL_VEHICLES="/nonexistent:$tmp/mine:$ROOT/vehicles" $BIN energy --list 2>&1); rc=$?
if [ $rc -eq 0 ] && echo "$l" | grep -q "^my_van .*$tmp/mine/my_van.yaml" &&
   echo "$l" | grep -q "^midsize_suv .*$tmp/mine/midsize_suv.yaml" && echo "$l" | grep -q '^class8_tractor '; then
  ok search_path_env_first
else ko search_path_env_first "rc=$rc $l"; fi
cp "$BIN" "$tmp/prefix/bin/wavefuel"
cp "$ROOT/vehicles/compact_sedan.yaml" "$tmp/prefix/vehicles/only_here.yaml"
l=$(WAVEFUEL_VEHICLES= "$tmp/prefix/bin/wavefuel" energy --list 2>&1); rc=$?
if [ $rc -eq 0 ] && [ "$(echo "$l" | tail -n +2 | wc -l)" -eq 1 ] && echo "$l" | grep -q "^only_here .*$tmp/prefix/vehicles/only_here.yaml"; then
  ok search_path_prefix_of_binary
else ko search_path_prefix_of_binary "rc=$rc $l"; fi
exit 0
