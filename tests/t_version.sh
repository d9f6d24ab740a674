#!/usr/bin/env bash
# The version a binary reports (src/util/version.c): `wavefuel --version` and a run's /meta/git_hash name the tree the
# binary was built from, `git describe --always --dirty` (an incremental build once kept an older tree's hash in
# every object a change did not touch). Skipped outside a git checkout. Prints "PASS name" / "FAIL name: why".
set -u
cd "$(dirname "$0")/.." || exit 1
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
if ! want=$(git describe --always --dirty 2>/dev/null); then
  echo "SKIP version_*: not a git checkout"
  exit 0
fi
ver=$(sed -n 's/^#define WF_VERSION "\(.*\)"/\1/p' include/wavefuel/version.h)
got=$("$BIN" --version)
if [ "$got" = "wavefuel $ver ($want)" ]; then echo "PASS version_option"
else echo "FAIL version_option: '$got', want 'wavefuel $ver ($want)'"; fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
if ! "$BIN" run tests/data/tiny_ring.yaml -q -o "$tmp/r.h5" >"$tmp/log" 2>&1; then
  echo "FAIL version_meta: the run failed: $(tail -3 "$tmp/log")"
  exit 0
fi
meta=$(/usr/bin/python3 -c 'import sys, h5py; print(h5py.File(sys.argv[1], "r")["meta/git_hash"][()].decode())' "$tmp/r.h5")
if [ "$meta" = "$want" ]; then echo "PASS version_meta"
else echo "FAIL version_meta: /meta/git_hash '$meta', want '$want'"; fi
