#!/usr/bin/env bash
# Cost of a safety filter per vehicle-step (docs/controllers.md#safety-filters): a ring of N IDM drivers with
# acceleration noise (tests/data/tiny_ring.yaml scaled up), one driver group, fused steps, one thread, run without a
# filter and with each filter kind, REPS times each in alternation; the step loop's wall time is /meta/wall_time_s of
# each result. Prints the best (smallest) wall time per variant, its ns per vehicle-step, and the filter's cost: the
# difference of the best times over the vehicle-steps. Also the share of vehicle-steps where the filter intervened.
#   bench/safety_cost/run.sh [N_VEHICLES] [DURATION_S] [REPS]      (defaults 100000 60 5)
set -eu
cd "$(dirname "$0")/../.."
N=${1:-100000} DUR=${2:-60} REPS=${3:-5}
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
L=$(/usr/bin/python3 -c "print($N * 25)")   # 25 m per vehicle: 20 m gaps, moderate density
BASE=(--set fleet.vehicles=$N --set road.length_m=$L --set time.duration_s=$DUR --set time.warmup_s=0
      --set time.output_interval_s=$DUR --set output.trajectories=false --threads 1 -q --force)
echo "machine: $(nproc) cores, $(uname -m); load: $(cut -d' ' -f1-3 /proc/loadavg); git $(git rev-parse --short HEAD)"
for r in $(seq "$REPS"); do
  for v in none gipps ttc; do
    extra=()
    [ "$v" != none ] && extra=(--set "fleet.drivers[0].safety.kind=$v")
    "$BIN" run tests/data/tiny_ring.yaml -o "$tmp/$v.$r.h5" "${BASE[@]}" "${extra[@]}"
  done
done
/usr/bin/python3 - "$tmp" "$REPS" "$N" "$DUR" <<'PY'
import sys, h5py
tmp, reps, n, dur = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
vs = n * round(dur / 0.1)
best = {}
for v in ("none", "gipps", "ttc"):
    walls = [h5py.File(f"{tmp}/{v}.{r}.h5")["meta/wall_time_s"][()] for r in range(1, reps + 1)]
    s = h5py.File(f"{tmp}/{v}.1.h5")["summary"]
    share = s["group_safety_share"][0] if "group_safety_share" in s else 0.0
    best[v] = min(walls)
    print(f"BENCH safety filter={v} n={n} vehicle_steps={vs} best_wall_s={best[v]:.4f} "
          f"ns_per_vehicle_step={1e9 * best[v] / vs:.2f} interventions_share={share:.4f}")
for v in ("gipps", "ttc"):
    print(f"BENCH safety_cost filter={v} ns_per_vehicle_step={1e9 * (best[v] - best['none']) / vs:.2f}")
PY
