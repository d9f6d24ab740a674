#!/usr/bin/env bash
# ThreadSanitizer over the whole test suite and over large runs (docs/reliability.md). gcc's libgomp is not
# instrumented, so TSan would see neither its barriers nor its fork/join and report false races; instead the
# tree is built with clang -fsanitize=thread -fopenmp, which links LLVM's libomp, and libomp loads Archer
# (libarcher.so via OMP_TOOL_LIBRARIES: LLVM's OMPT tool that tells TSan about OpenMP's synchronisation).
# Runs use OMP_NUM_THREADS=2 and halt_on_error, so a race fails the test that triggered it. The engine runs its
# loops serially below WF_PAR_MIN = 4096 vehicles (src/core/block.h), so most tests are serial: the last part runs a
# fleet with 4096 vehicles in each of the six car-following models, through every integrator, so that every
# parallel loop of the step runs on two threads. Usage: tools/tsan-tests.sh   (TSAN_BUILD=build-tsan)
set -u
cd "$(dirname "$0")/.." || exit 1
TB=${TSAN_BUILD:-build-tsan}
ARCHER=${ARCHER_LIB:-$(ls /usr/lib/llvm-*/lib/libarcher.so 2>/dev/null | sort -V | tail -n 1)}

probe() {
  printf '#include <omp.h>\nint main(void) { int s = 0;\n#pragma omp parallel reduction(+:s)\n s += omp_get_thread_num();\n return s < 0; }\n' |
    clang -x c -fsanitize=thread -fopenmp -o /dev/null - >/dev/null 2>&1
}
if ! command -v clang >/dev/null 2>&1 || ! probe || [ -z "$ARCHER" ]; then
  ./tools/install-deps.sh fuzz || exit 1
  ARCHER=$(ls /usr/lib/llvm-*/lib/libarcher.so 2>/dev/null | sort -V | tail -n 1)
  probe && [ -n "$ARCHER" ] || { echo "tsan-tests.sh: clang -fsanitize=thread -fopenmp or libarcher.so unusable" >&2; exit 1; }
fi

echo "building $TB with clang -fsanitize=thread -fopenmp (libomp), Archer: $ARCHER"
make --no-print-directory -j"$(nproc)" BUILD="$TB" CC=clang \
  CFLAGS="-O1 -g -fno-omit-frame-pointer -fsanitize=thread" LDFLAGS="-fsanitize=thread" \
  BIN="$TB/bin/wavefuel" LIBA="$TB/lib/libwavefuel.a" tests >"$TB.log" 2>&1 ||
  { tail -30 "$TB.log" >&2; echo "tsan-tests.sh: build failed (log: $TB.log)" >&2; exit 1; }

# halt_on_error + exitcode: the first race ends the program with status 66, which the suite counts as a
# failure; the report goes to the test's output (shown by tests/run.sh for failing tests).
export TSAN_OPTIONS=${TSAN_OPTIONS:-halt_on_error=1 exitcode=66 ignore_noninstrumented_modules=1 history_size=4}
export OMP_TOOL_LIBRARIES=$ARCHER
export OMP_NUM_THREADS=2
# A program built with clang -fsanitize=thread -fopenmp dies of SIGBUS inside libomp's start-up (TSan's strcmp
# interceptor) under a file size limit of 300 kB or less, even `int main(void) { return omp_get_max_threads(); }`
# (LLVM 14; 500 kB is fine): the tests' ulimit -f cases below 512 kB are skipped here (they run in every other
# build).
export WF_TEST_MIN_FSIZE_KB=512
# $TB/bin/wavefuel has no $TB/vehicles: the repository's classes by path (docs/energy.md, the class search path).
export WAVEFUEL_VEHICLES="$PWD/vehicles"
export FUZZ_SMOKE_SECONDS=0 # the libFuzzer part is an ASan build: nothing to learn about threads there
BUILD="$TB" WAVEFUEL_BIN="$TB/bin/wavefuel" ./tests/run.sh
suite=$?

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cat > "$tmp/parallel.yaml" <<'Y'
# Every per-vehicle and per-model loop of the step above WF_PAR_MIN (4096, src/core/block.h): 6 x 4096 vehicles.
name: tsan_parallel
seed: 11
road:
  length_m: 614400
  grade: {points: [[0, 0.01], [307200, -0.01]]}
time: {duration_s: 1, dt_s: 0.1, output_interval_s: 0.1, warmup_s: 0.1}
fleet:
  vehicles: 24576
  placement: random
  classes:
    - {class: midsize_sedan, fraction: 0.5}
    - {class: class8_tractor, fraction: 0.25}
    - {class: midsize_suv, fraction: 0.25}
  drivers:
    - {model: idm, count: 4096, noise_mps2: 0.3, feasible_accel: clip,
       heterogeneity: {distribution: normal, spread: {T_s: 0.1, v0_mps: 0.1}}}
    - {model: ovm, count: 4096}
    - {model: gipps, count: 4096}
    - {model: acc, count: 4096}
    - {model: follower_stopper, count: 4096}
    - {model: pi_saturation, count: 4096}
initial: {state: rest, jitter_m: 0.2}
output: {trajectories: true}
Y
pass=0 fail=0
for integ in ballistic euler rk4 cvode arkode; do
  # The SUNDIALS integrators take many right-hand-side calls per step: two steps are enough for them.
  dur=1; case $integ in cvode|arkode) dur=0.2 ;; esac
  start=$SECONDS
  if "$TB/bin/wavefuel" run "$tmp/parallel.yaml" -o "$tmp/p_$integ.h5" -q --set time.integrator=$integ \
       --set time.duration_s=$dur >"$tmp/$integ.log" 2>&1; then
    pass=$((pass + 1)); echo "PASS parallel_run_$integ ($((SECONDS - start)) s, 24576 vehicles, 2 threads)"
  else
    fail=$((fail + 1)); echo "FAIL parallel_run_$integ"; grep -v 'Archer detected' "$tmp/$integ.log" | head -40 | sed 's/^/    /'
  fi
done
echo "parallel runs: $pass passed, $fail failed"
[ "$suite" -eq 0 ] && [ "$fail" -eq 0 ]
