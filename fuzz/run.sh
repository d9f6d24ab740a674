#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (address + undefined sanitizers) in build-fuzz/ and runs each for
# FUZZ_SECONDS (default 60) on its seed corpus fuzz/corpus/TARGET plus the fixed crash regressions. New inputs go to
# build-fuzz/corpus/TARGET (kept between runs, never in the tree). A crash or leak is copied into
# fuzz/crashes/TARGET/, where tests/t_fuzz_smoke.sh replays it until it is fixed; timeouts and out-of-memory
# inputs are left in build-fuzz/artifacts/TARGET/. Exits 1 if any target found anything.
# Usage: fuzz/run.sh [TARGET...]   (FUZZ_SECONDS, FUZZ_CC=clang, FUZZ_BUILD=build-fuzz)
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
SECONDS_EACH=${FUZZ_SECONDS:-60}
FUZZ_CC=${FUZZ_CC:-clang}
FB=${FUZZ_BUILD:-build-fuzz}
TARGETS=("$@")
[ ${#TARGETS[@]} -eq 0 ] && TARGETS=(scenario vehicle csv)

# clang with the libFuzzer and sanitizer runtimes: probe by building a trivial fuzzer; install if it fails.
probe() {
  echo 'int LLVMFuzzerTestOneInput(const unsigned char *d, unsigned long n) { (void)d; (void)n; return 0; }' |
    "$FUZZ_CC" -x c -fsanitize=fuzzer,address,undefined -o /dev/null - >/dev/null 2>&1
}
if ! probe; then
  ./tools/install-deps.sh fuzz || exit 1
  probe || { echo "fuzz/run.sh: $FUZZ_CC cannot build a libFuzzer target" >&2; exit 1; }
fi

SAN="-fsanitize=address,undefined -fno-sanitize-recover=undefined"
make --no-print-directory -j"$(nproc)" BUILD="$FB" CC="$FUZZ_CC" \
  CFLAGS="-O1 -g -fno-omit-frame-pointer $SAN -fsanitize=fuzzer-no-link" LDFLAGS="$SAN" \
  LIBA="$FB/lib/libwavefuel.a" $(printf "$FB/fuzz/%s_fuzzer " "${TARGETS[@]}") >"$FB.log" 2>&1 ||
  { tail -30 "$FB.log" >&2; echo "fuzz/run.sh: build failed (log: $FB.log)" >&2; exit 1; }

# The targets' scratch directories (left behind by inputs that abort) go under build-fuzz/tmp, emptied here.
export TMPDIR="$PWD/$FB/tmp"
rm -rf "$TMPDIR" && mkdir -p "$TMPDIR"
trap 'rm -rf "$TMPDIR"' EXIT
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
found=0
for t in "${TARGETS[@]}"; do
  work="$FB/corpus/$t" art="$FB/artifacts/$t/"
  mkdir -p "$work" "$art" "fuzz/crashes/$t"
  log="$FB/fuzz-$t.log"
  ls "$art" > "$FB/artifacts/$t.before"
  # Fixed crash regressions seed the run (they reach deep paths); open-* ones (reported, unfixed) would stop it
  # at once, so they stay out.
  for f in fuzz/crashes/$t/*; do
    case "$(basename "$f")" in open-*) ;; *) [ -f "$f" ] && cp -n "$f" "$work/" ;; esac
  done
  # -timeout: a single input taking 10 s is a finding (a hang); -rss_limit_mb bounds hostile allocations.
  for _ in 1 2 3; do
    "$FB/fuzz/${t}_fuzzer" -max_total_time="$SECONDS_EACH" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
      -dict="fuzz/$t.dict" -artifact_prefix="$art" "$work" "fuzz/corpus/$t" \
      </dev/null >"$log" 2>&1
    rc=$?
    # A binary linked a moment ago can still be "busy" (ETXTBSY, status 126) for a short while.
    [ $rc -eq 126 ] && grep -q 'Text file busy' "$log" && { sleep 2; continue; }
    break
  done
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -n 1)
  cov=$(grep -oE 'cov: [0-9]+' "$log" | tail -n 1)
  printf '%-9s %3ss  %9s executions  %-10s corpus %5s files  exit %d\n' "$t" "$SECONDS_EACH" "${execs:-?}" \
    "${cov:-cov: ?}" "$(ls "$work" | wc -l)" "$rc"
  new=$(ls "$art" | grep -vxF -f "$FB/artifacts/$t.before")
  if [ "$rc" -ne 0 ] || [ -n "$new" ]; then
    found=1
    for f in $new; do
      case "$f" in crash-*|leak-*) cp -n "$art$f" "fuzz/crashes/$t/" && echo "  regression input: fuzz/crashes/$t/$f" ;;
                   *) echo "  input: $art$f" ;; esac
    done
    grep -m1 -E 'ERROR|runtime error|property violated|broken error contract' "$log" | sed 's/^/  /'
    echo "  log: $log"
  fi
done
exit $found
