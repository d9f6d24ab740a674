#!/usr/bin/env bash
# Rewrites the generated tables of the docs from the library's tables (build/tools/keydoc, built by `make tests`):
# every block between `<!-- keydoc ARGS begin -->` and `<!-- keydoc end -->` in docs/*.md becomes the output of
# `keydoc ARGS` (ARGS: "keys SECTION ring|corridor", "params MODEL", "integrators").
#   tools/gen-key-docs.sh           rewrite the docs in place
#   tools/gen-key-docs.sh --check   change nothing; exit 1 and name each block that differs, or each table of
#                                   `keydoc list` that no doc shows
set -u
cd "$(dirname "$0")/.." || exit 1
KEYDOC=${KEYDOC:-${BUILD:-build}/tools/keydoc}
DOCS=${KEY_DOCS_DIR:-docs} # the test points this at a copy
[ -x "$KEYDOC" ] || { echo "gen-key-docs: $KEYDOC not built (make tests)" >&2; exit 2; }
exec /usr/bin/python3 - "$KEYDOC" "${1:-}" "$DOCS"/*.md <<'PY'
import re, subprocess, sys
keydoc, mode, files = sys.argv[1], sys.argv[2], sys.argv[3:]
check = mode == '--check'
block = re.compile(r'(<!-- keydoc (.+?) begin -->\n)(.*?)(<!-- keydoc end -->)', re.S)
bad, shown = 0, set()
for path in files:
    text = open(path, encoding='utf-8').read()
    def repl(m):
        global bad
        args = m.group(2).split()
        shown.add(' '.join(args))
        r = subprocess.run([keydoc] + args, capture_output=True, text=True)
        if r.returncode:
            print(f'{path}: keydoc {" ".join(args)}: {r.stderr.strip()}'); bad += 1
            return m.group(0)
        if r.stdout != m.group(3):
            if check: print(f'{path}: the table "keydoc {" ".join(args)}" differs from the library (tools/gen-key-docs.sh rewrites it)')
            bad += check
        return m.group(1) + r.stdout + m.group(4)
    new = block.sub(repl, text)
    if not check and new != text:
        open(path, 'w', encoding='utf-8').write(new)
        print(f'rewrote {path}')
for want in subprocess.run([keydoc, 'list'], capture_output=True, text=True, check=True).stdout.split('\n'):
    if want and want not in shown:
        print(f'no doc shows the table "keydoc {want}" (add <!-- keydoc {want} begin --> ... <!-- keydoc end -->)'); bad += 1
sys.exit(1 if bad else 0)
PY
