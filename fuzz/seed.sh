#!/usr/bin/env bash
# Regenerates the seed corpora in fuzz/corpus/TARGET/ from the repository's own files (scenarios, test data,
# vehicle classes, drive cycles) plus a few hand-written inputs that reach every section and reader. The
# fuzzers' own discoveries stay in build-fuzz/corpus/; only seeds and crash regressions live in the tree.
set -euo pipefail
cd "$(dirname "$0")/.."
C=fuzz/corpus
rm -rf "$C"
mkdir -p "$C/scenario" "$C/vehicle" "$C/csv"

# --- scenario: YAML, then optionally a NUL and one --set assignment per line ---
for f in scenarios/*.yaml tests/data/*.yaml; do cp "$f" "$C/scenario/$(basename "$f")"; done
{ cat tests/data/tiny_ring.yaml; printf '\0fleet.vehicles=30\nroad.length_m=400\ntime.dt_s=0.2\nfleet.drivers[0].params.T_s=1.5'; } \
  > "$C/scenario/tiny_with_sets"
cat > "$C/scenario/every_key.yaml" <<'Y'
name: every_key
seed: 42
road:
  type: ring
  length_m: 500
  speed_limit_mps: 25
  grade:
    points: [[0, 0.0], [100, 0.02], [250, 0.0], [400, -0.02]]
time: {duration_s: 30, dt_s: 0.1, output_interval_s: 1.0, warmup_s: 5, integrator: euler}
fleet:
  vehicles: 12
  placement: interleaved
  classes:
    - {class: compact_sedan, count: 8, length_m: 4.5}
    - {class: class8_tractor, count: 4}
  drivers:
    - name: human
      model: idm
      count: 9
      params: {v0_mps: 30, T_s: 1.2, s0_m: 2.0, a_mps2: 1.0, b_mps2: 1.5, delta: 4}
      heterogeneity: {distribution: uniform, spread: {v0_mps: 0.1, T_s: 0.2}}
      noise_mps2: 0.2
      accel_max_mps2: 3
      decel_max_mps2: 8
      feasible_accel: clip
    - {model: ovm, count: 2}
    - {model: gipps, count: 1}
initial:
  state: rest
  jitter_m: 0.5
  perturbation: {vehicle: 3, dx_m: 1.0, dv_mps: 0.5}
statistics: {v_stop_mps: 0.4, v_go_mps: 2.5, hard_brake_mps2: 1.5, wave_speed_mps: 3}
output: {path: out.h5, trajectories: true, trajectory_interval_s: 2.0}
Y
cat > "$C/scenario/explicit.yaml" <<'Y'
road: {length_m: 200}
time: {duration_s: 10}
fleet:
  vehicles: 5
  placement: explicit
  classes:
    - {class: midsize_suv, indices: [0, 2, 4]}
    - {class: midsize_pickup, indices: [1, 3]}
  drivers:
    - {model: idm, indices: [0, 1, 2]}
    - {model: gipps, indices: [3, 4]}
Y

# --- vehicle: class files ---
for f in vehicles/*.yaml; do cp "$f" "$C/vehicle/$(basename "$f")"; done

# --- csv: a selector byte (0 grade, 1 energy, 2 cycle, 3 tabulated, 4 raw, 5 inflow, 6 elevation), then the file ---
seed_csv() { local name=$1 mode=$2; { printf "\\x0$mode"; cat; } > "$C/csv/$name"; }
printf 'x_m,grade_rad\n0,0\n250,0.01\n500,0\n750,-0.01\n' | seed_csv grade 0
printf '# comment\r\n0,0.01\r\n500,-0.01\r\n' | seed_csv grade_crlf 0
printf 'v,a,theta\n0,0,0\n10,1,0.01\n30,-2,-0.02\n-1,0,0\n' | seed_csv energy 1
printf '\xef\xbb\xbfv,a,theta\n5,0.5,0\n' | seed_csv energy_bom 1
for f in ../shared/data/cycles/udds.csv ../shared/data/cycles/us06.csv; do # next to the repository
  [ -f "$f" ] && head -40 "$f" | seed_csv "cycle_$(basename "$f" .csv)" 2
done
printf '0,0\n1,1.5\n2.5,3\n4,0\n' | seed_csv cycle_noheader 2
/usr/bin/python3 - <<'PY' | seed_csv table 3
# A complete 3 x 3 x 3 grid in the release's format (values arbitrary but finite; Infeasible 0 or 1).
print("Velocity,Acceleration,Road Grade,Fuel Rate,Infeasible")
for v in (0, 10, 20):
    for a in (-1, 0, 1):
        for t in (-0.02, 0, 0.02):
            print(f"{v:g},{a:g},{t:g},{0.2 + 0.01 * v + 0.3 * max(a, 0) + 5 * t:.6g},{int(a > 0 and v > 15)}")
PY
printf '1,2,3,4,5\n6,7,8,9,10\n' | seed_csv raw5 4
for f in scenarios/data/*.csv; do
  case "$(head -n 1 "$f")" in
    time_s,*) seed_csv "inflow_$(basename "$f" .csv)" 5 < "$f" ;;
    x_m,z_m*) seed_csv "elevation_$(basename "$f" .csv)" 6 < "$f" ;;
  esac
done
echo "seeded: $(ls "$C/scenario" | wc -l) scenario, $(ls "$C/vehicle" | wc -l) vehicle, $(ls "$C/csv" | wc -l) csv"
