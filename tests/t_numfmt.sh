#!/usr/bin/env bash
# Numbers in messages (src/util/numfmt.c, wf_num): for 20000 doubles (random bit patterns, values users type such as
# 0.3 and 2.05, and the edges: signed zeros, subnormals, the largest double), the text must read back as the same
# double and have as few significant digits as Python's repr (David Gay's shortest round-trip, an independent
# implementation). Also a message of `wavefuel run` shows the user's 2.05, not 2.0499999999999998.
# Prints "PASS name" / "FAIL name: why".
set -u
cd "$(dirname "$0")/.." || exit 1
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

cat > "$tmp/num.c" <<'C'
/* Reads 64-bit patterns (hex, one per line), prints wf_num of each double. */
#include <inttypes.h>
#include <stdio.h>
#include <string.h>
#include "util/numfmt.h"
int main(void)
{
    char line[64];
    while (fgets(line, sizeof line, stdin)) {
        uint64_t bits;
        double x;
        if (sscanf(line, "%" SCNx64, &bits) != 1) return 1;
        memcpy(&x, &bits, sizeof x);
        printf("%s\n", WF_NUM(x));
    }
    return 0;
}
C
# Compiled from the source, not linked with the library under test (a sanitizer build's archive needs its flags).
if ! cc -std=c11 -D_GNU_SOURCE -Isrc -Iinclude "$tmp/num.c" src/util/numfmt.c -lm -o "$tmp/num" 2>"$tmp/cc.log"; then
  ko shortest_round_trip "cannot build the driver: $(head -3 "$tmp/cc.log")"; exit 0
fi
/usr/bin/python3 - "$tmp/num" <<'PY'
import random, struct, subprocess, sys
random.seed(19)
vals = [0.3, 0.1 + 0.2, 2.05, 0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 1.7976931348623157e308, 100000.0,
        1e6, 123456.75, 1e-7, 150.0, -0.5, 1e308, 9007199254740993.0]
while len(vals) < 20000:
    x = struct.unpack("<d", struct.pack("<Q", random.getrandbits(64)))[0]
    if x == x and abs(x) != float("inf"):
        vals.append(x)
    vals.append(round(random.uniform(-1000, 1000), random.randint(0, 6)))  # numbers as people type them
vals = vals[:20000]
inp = "".join("%016x\n" % struct.unpack("<Q", struct.pack("<d", v))[0] for v in vals)
out = subprocess.run([sys.argv[1]], input=inp, capture_output=True, text=True, check=True).stdout.split()
def digits(s):
    m = s.lower().lstrip("-").split("e")[0].replace(".", "").lstrip("0").rstrip("0")
    return max(len(m), 1)
bad = []
for v, s in zip(vals, out):
    back = float(s)
    if struct.pack("<d", back) != struct.pack("<d", v):
        bad.append(f"{v!r} printed {s} reads back {back!r}")
    elif digits(s) != digits(repr(v)):
        bad.append(f"{v!r} printed {s}: {digits(s)} digits, repr has {digits(repr(v))}")
if len(out) != len(vals) or bad:
    print(f"FAIL shortest_round_trip: {len(bad)} of {len(vals)}: {bad[:5]}")
else:
    print(f"PASS shortest_round_trip ({len(vals)} doubles: same value, as few digits as repr)")
PY

printf 'road: {length_m: 230}\ntime: {duration_s: 2.05, dt_s: 0.1}\nfleet:\n  vehicles: 5\n  classes: [{class: midsize_sedan, count: 5}]\n  drivers: [{model: idm, count: 5}]\n' > "$tmp/d.yaml"
msg=$("$BIN" run "$tmp/d.yaml" -o "$tmp/d.h5" -q 2>&1); rc=$?
if [ $rc -eq 2 ] && echo "$msg" | grep -qF "time.duration_s (2.05 s) must be a whole multiple of time.dt_s (0.1 s)"; then
  ok message_shows_the_value_typed; else ko message_shows_the_value_typed "rc=$rc $msg"; fi
