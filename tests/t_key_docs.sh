#!/usr/bin/env bash
# The key tables of the docs (scenarios.md, corridors.md) and the parameter tables (models.md, controllers.md) are
# generated from the library's tables by tools/gen-key-docs.sh. This test: 1) the docs agree with the tables and show
# every table `keydoc list` names (the inventory comes from the registries, never counted here); 2) the check does
# fail on a copy of the docs with one generated cell changed, and on a copy with one generated block removed.
set -u
cd "$(dirname "$0")/.." || exit 1
BUILD=${BUILD:-build}
export KEYDOC="$BUILD/tools/keydoc"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

out=$(tools/gen-key-docs.sh --check 2>&1); rc=$?
if [ $rc -eq 0 ]; then ok "key_docs_match"; else ko "key_docs_match" "$out"; fi

n=$("$KEYDOC" list | wc -l)
[ "$n" -ge 1 ] && ok "keydoc_list ($n tables)" || ko "keydoc_list" "keydoc list printed nothing"

# 1) one cell of every generated block changed in turn must be reported, naming that block.
cp docs/*.md "$tmp/"
blocks=$(grep -ho '<!-- keydoc .* begin -->' docs/*.md | sed 's/<!-- keydoc \(.*\) begin -->/\1/')
bad=0
while IFS= read -r b; do
  rm -f "$tmp"/*.md; cp docs/*.md "$tmp/"
  f=$(grep -lF -- "<!-- keydoc $b begin -->" "$tmp"/*.md | head -1)
  # Append a character to the last cell of the block's first data row (the line after the header separator).
  /usr/bin/python3 - "$f" "$b" <<'PY'
import sys
path, args = sys.argv[1], sys.argv[2]
lines = open(path, encoding='utf-8').read().split('\n')
i = lines.index(f'<!-- keydoc {args} begin -->')
lines[i + 3] = lines[i + 3][:-1] + 'X |'
open(path, 'w', encoding='utf-8').write('\n'.join(lines))
PY
  msg=$(KEY_DOCS_DIR="$tmp" tools/gen-key-docs.sh --check 2>&1); rc=$?
  if [ $rc -eq 0 ] || ! printf '%s' "$msg" | grep -qF "keydoc $b\""; then bad=1; ko "key_docs_detects_change ($b)" "rc=$rc: $msg"; fi
done <<< "$blocks"
[ $bad -eq 0 ] && ok "key_docs_detects_change ($(printf '%s\n' "$blocks" | wc -l) blocks)"

# 2) a table of `keydoc list` that no doc shows must be reported.
rm -f "$tmp"/*.md; cp docs/*.md "$tmp/"
first=$("$KEYDOC" list | head -1)
/usr/bin/python3 - "$tmp" "$first" <<'PY'
import glob, re, sys
d, args = sys.argv[1], sys.argv[2]
for p in glob.glob(d + '/*.md'):
    s = open(p, encoding='utf-8').read()
    t = re.sub(r'<!-- keydoc ' + re.escape(args) + r' begin -->\n.*?<!-- keydoc end -->\n', '', s, flags=re.S)
    if t != s: open(p, 'w', encoding='utf-8').write(t)
PY
msg=$(KEY_DOCS_DIR="$tmp" tools/gen-key-docs.sh --check 2>&1); rc=$?
if [ $rc -ne 0 ] && printf '%s' "$msg" | grep -qF "no doc shows the table \"keydoc $first\""; then ok "key_docs_detects_missing"
else ko "key_docs_detects_missing" "rc=$rc: $msg"; fi
