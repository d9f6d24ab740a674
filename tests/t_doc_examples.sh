#!/usr/bin/env bash
# The command-and-output examples of README.md and docs/*.md marked `<!-- example -->` (convention and comparison
# rules: tests/docex.py) run and give the output the docs show: a change that moves a quoted figure fails here until
# the doc follows. First the runner's own rules, on blocks whose commands are `printf` (each rule once passing and
# once failing; all in one document, run once), then a real example with one quoted figure changed, then every
# marked example.
set -u
cd "$(dirname "$0")/.." || exit 1
PY=/usr/bin/python3
DOCEX=tests/docex.py
# The Python examples load lib/libwavefuel.so of the default build (`make test` builds it; a sanitizer run of the
# suite builds only its own tree, so build it here as tests/t_python.sh does).
make --no-print-directory -s python BUILD=build >/dev/null || { echo "FAIL doc_examples_python_build: make python"; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

# expect NAME RESULT MARK COMMAND EXPECTED...: appends a block to one document of the runner's rules; after all of
# them, docex runs that document once and each block must give RESULT (0: PASS, 1: FAIL).
rules="$tmp/rules.md"; cases=()
expect() {
  local name=$1 want=$2 mark=$3 cmd=$4; shift 4
  { echo "text"; echo "$mark"; } >>"$rules"
  cases+=("$name $want $(($(wc -l <"$rules") + 1))")
  { echo '```'; echo "\$ $cmd"; printf '%s\n' "$@"; echo '```'; } >>"$rules"
}
m='<!-- example -->'
expect exact 0 "$m" "printf 'fleet 22 3728.84 15.675\n'" 'fleet 22 3728.84 15.675'
expect number_moved 1 "$m" "printf 'fleet 22 3728.84 15.676\n'" 'fleet 22 3728.84 15.675'
expect count_moved 1 "$m" "printf 'fleet 23 3728.84 15.675\n'" 'fleet 22 3728.84 15.675'
expect within_tolerance 0 '<!-- example tolerance=1e-4 -->' "printf '15.676\n'" '15.675'
expect outside_tolerance 1 '<!-- example tolerance=1e-5 -->' "printf '15.676\n'" '15.675'
expect wall_time_masked 0 "$m" "printf 'x (2 threads, wall 9.1 s, 1.2e+03 vehicle-steps/s)\n'" \
  'x (2 threads, wall 0.046 s, 2.85e+06 vehicle-steps/s)'
expect threads_not_masked 1 "$m" "printf 'x (3 threads, wall 9.1 s)\n'" 'x (2 threads, wall 0.046 s)'
expect sweep_times_masked 0 "$m" "printf '[1/4] run 0 ok (3.5 s)\nran 4 now in 9.9 s (1.5e+03 runs/h)\n'" \
  '[1/4] run 0 ok (0.42 s)' 'ran 4 now in 10.266 s (1.578e+04 runs/h)'
expect path_normalised 0 "$m" "printf 'class x, $PWD/vehicles/x.yaml\n'" 'class x, /work/main/vehicles/x.yaml'
expect path_other_file 1 "$m" "printf 'class x, $PWD/vehicles/y.yaml\n'" 'class x, /work/main/vehicles/x.yaml'
expect digits_in_words_exact 1 "$m" "printf 'cycle us07 ac1f2369525fe89b\n'" 'cycle us06 ac1f2369525fe89a'
expect blanks_collapsed 0 "$m" "printf 'a   1\n'" 'a 1'
expect ellipsis 0 "$m" "printf 'head\n1\n2\n3\ntail 4\n'" 'head' '...' 'tail 4'
expect ellipsis_tail_wrong 1 "$m" "printf 'head\n1\n2\ntail 5\n'" 'head' '...' 'tail 4'
expect missing_line 1 "$m" "printf 'a\n'" 'a' 'b'
expect extra_line 1 "$m" "printf 'a\nb\n'" 'a'
expect exit_status 1 "$m" "printf 'a\n'; false" 'a'
expect status_option 0 '<!-- example status=3 -->' "printf 'a\n'; exit 3" 'a'
expect pipefail 1 "$m" "false | cat" ''
expect continued_command 0 "$m" "printf '%s\n' 'a" "  b' | cat" 'a' '  b'
expect cwd_option 0 '<!-- example cwd=output -->' "basename \"\$PWD\"" 'output'
expect cwd_missing 1 '<!-- example cwd=nowhere -->' "true"
expect setup_option 0 '<!-- example setup="echo 7 > f" -->' "cat f" '7'
out=$($PY $DOCEX "$rules" 2>&1); rc=$?
for c in "${cases[@]}"; do
  read -r name want line <<<"$c"
  res=$(grep -o "^[A-Z]* example $rules:$line\b" <<<"$out" | cut -d' ' -f1)
  if { [ "$want" -eq 0 ] && [ "$res" = PASS ]; } || { [ "$want" -eq 1 ] && [ "$res" = FAIL ]; }; then ok "docex_$name"
  else ko "docex_$name" "${res:-no result} for the block at line $line, expected $([ "$want" -eq 0 ] && echo PASS || echo FAIL)"; fi
done
if [ "$rc" -eq 1 ] && ! grep -q Traceback <<<"$out"; then ok "docex_rules_exit_status"
else ko "docex_rules_exit_status" "exit $rc, expected 1 (some blocks fail): $out"; fi

# doc FILE STATUS TEXT: a document written with printf; docex must exit with STATUS.
doc() {
  printf "$3" >"$tmp/$1.md"
  out=$($PY $DOCEX "$tmp/$1.md" 2>&1); rc=$?
  if [ "$rc" -eq "$2" ] && ! grep -q Traceback <<<"$out"; then ok "docex_$1"; else ko "docex_$1" "exit $rc, expected $2: $out"; fi
}
doc unknown_option 2 '<!-- example tolerence=1 -->\n```\n$ true\n```\n'
doc output_before_command 2 '<!-- example -->\n```\nx\n$ true\n```\n'
doc mark_without_block 2 '<!-- example -->\ntext\n'
doc block_not_closed 2 '<!-- example -->\n```\n$ true\n'
doc unmarked_block_not_run 0 'text\n```\n$ false\nnothing\n```\n'

# A real example with one quoted figure moved (the FollowerStopper run's fleet fuel) must fail and name the line.
cp docs/controllers.md "$tmp/controllers.md"
sed -i 's/^\(fleet  *22  *\)2903\.27/\12903.35/' "$tmp/controllers.md"
if cmp -s docs/controllers.md "$tmp/controllers.md"; then
  ko "docex_moved_figure" "docs/controllers.md has no line 'fleet 22 2903.27' to change"
else
  out=$($PY $DOCEX "$tmp/controllers.md" 2>&1); rc=$?
  if [ "$rc" -eq 1 ] && grep -q "expected 'fleet  *22  *2903.35 .*', got 'fleet  *22  *2903.27 " <<<"$out"; then
    ok "docex_moved_figure"
  else ko "docex_moved_figure" "exit $rc: $out"; fi
fi

# Every marked example of the README and the docs.
n=$(grep -c '^<!-- example' README.md docs/*.md | awk -F: '{ s += $2 } END { print s }')
[ "$n" -ge 1 ] && ok "doc_examples_marked ($n blocks)" || ko "doc_examples_marked" "no marked example"
$PY $DOCEX README.md docs/*.md
