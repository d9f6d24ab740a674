#!/usr/bin/env bash
# One road split across MPI ranks (`mpirun -n R bin/wavefuel-mpi run`, issue 20). A ring: the result file equals
# `wavefuel run` of the same scenario in every dataset outside /meta (and /meta/steps_done, /meta/completed), bit for
# bit, for 2 and 3 ranks, 1 and 2 threads, time-blocked windows of 16 steps and one step at a time: a graded
# heterogeneous noisy ring with two classes and a speed limit, a ring whose initial equilibrium sums run across the
# ranks' shares (each rank builds only its own) and whose initial overlaps are found by one rank alone, a checkpoint
# of one process resumed on 3 ranks that read back only their shares, controllers with memory under a safety filter, a
# ring whose overlaps are repaired, a numerical fault on rank 1 (the same exit status, message and partial file); a
# run stopped by SIGTERM (to mpirun, or to rank 1 alone) resumes on another rank count and in one process to the
# uninterrupted result; what the ranks cannot split is refused with exit status 2, the key named and no file written;
# uneven shares are refused or give the one-process result. A corridor: the same for 2, 3 and 4 ranks, 1 and 2
# threads, with detectors at and beside the cuts between the ranks' segments, overlaps repaired across them,
# time-blocked windows (the halo of the rank ahead stepped again on each rank; windows redone on every rank), a stop
# by SIGTERM (one step at a time and in windows) resumed on another rank count and in one process, and its own
# refusals.
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
MPIBIN=${WAVEFUEL_MPI_BIN:-bin/wavefuel-mpi}
PY=/usr/bin/python3
. tests/scaffold.sh

if ! command -v mpicc >/dev/null 2>&1 || ! command -v mpirun >/dev/null 2>&1; then
  echo "NOTE t_mpi: mpicc/mpirun not installed, MPI tests skipped (tools/install-deps.sh mpi)"
  exit 0
fi
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
# Waiting ranks yield their core: this machine has 2, the tests run up to 4 ranks beside other tests.
export OMPI_MCA_mpi_yield_when_idle=1
# The default build tree: a sanitizer run of the suite (BUILD=build-san in the environment) must not mix its objects.
if ! make -s --no-print-directory mpi BUILD=build >"$tmp/make_mpi.log" 2>&1; then
  ko build_mpi "make mpi failed: $(tail -3 "$tmp/make_mpi.log")"; exit 1
fi

# mpi R ARGS...: wavefuel-mpi on R ranks (this machine has 2 cores: oversubscribed, unbound), bounded by a timeout so
# that a hung job fails this test instead of hanging the suite (MPI_TIMEOUT seconds, 150 unless set).
mpi() { local r=$1; shift; timeout -k 10 "${MPI_TIMEOUT:-150}" mpirun -n "$r" --oversubscribe --bind-to none "$MPIBIN" "$@"; }

# same A B [META...]: the two results are the same bits outside /meta (tests/h5same.py)
same() { $PY tests/h5same.py "$@"; }

# ranks LOG R THREADS: the run really had R ranks of THREADS threads (its header line: "2 threads x 3 processes").
ranks() {
  grep -q "[(, ]$3 threads x $2 processes," "$1" ||
    { echo "the header does not say '$3 threads x $2 processes': $(head -1 "$1")"; return 1; }
}

# mpi_same NAME REF R THREADS BLOCK SCENARIO [--set ...]: the MPI run of the scenario equals REF.
mpi_same() {
  local name=$1 ref=$2 r=$3 th=$4 bs=$5 out msg rc; shift 5
  out="$tmp/$name.h5"
  mpi "$r" run "$@" -o "$out" --threads "$th" --set time.block_steps="$bs" >"$tmp/$name.log" 2>&1; rc=$?
  if [ $rc -ne 0 ]; then ko "$name" "rc $rc: $(tail -4 "$tmp/$name.log")"; return; fi
  if msg=$(ranks "$tmp/$name.log" "$r" "$th" && same "$ref" "$out" 2>&1); then ok "$name ($msg)"; else ko "$name" "$msg"; fi
}

# (a) A graded ring (net climb 0 over the lap) with a speed limit: 3000 vehicles (12 blocks: 6 or 4 per rank) of two
# classes, heterogeneous noisy IDM with the feasible clip; a record every step and a warm-up ending between windows.
cat >"$tmp/het.yaml" <<'EOF'
seed: 11
road:
  length_m: 80000
  speed_limit_mps: 24
  grade: {points: [[0, 0.0], [20000, 0.02], [40000, 0.0], [60000, -0.02]]}
time: {duration_s: 30, dt_s: 0.1, output_interval_s: 0.1, warmup_s: 3.3}
fleet:
  vehicles: 3000
  placement: random
  classes:
    - {class: midsize_sedan, fraction: 0.7}
    - {class: class8_tractor, fraction: 0.3}
  drivers:
    - {model: idm, fraction: 1, noise_mps2: 0.3, feasible_accel: clip,
       heterogeneity: {spread: {T_s: 0.2, v0_mps: 0.1, a_mps2: 0.1}}}
initial: {state: equilibrium, jitter_m: 0.5}
output: {trajectories: false}
EOF
run "$tmp/het.yaml" -o "$tmp/het_ref.h5" --threads 1 --set time.block_steps=1
for r in 2 3; do
  for th in 1 2; do
    for bs in 16 1; do
      mpi_same "graded_ring_R${r}_threads${th}_block${bs}" "$tmp/het_ref.h5" $r $th $bs "$tmp/het.yaml"
    done
  done
done

# (a2) Each rank builds only its share of the fleet (docs/mpi.md, Memory). 13 000 heterogeneous vehicles: the
# equilibrium speed sums 4 blocks of 4096, two of which run past a share's end on 3 ranks ([4096, 8192) from rank 0
# into rank 1, [8192, 12288) from rank 1 into rank 2); PI with saturation, whose memory starts from its leader's speed;
# rank 1's first vehicle (the leader of rank 0's last) perturbed, jitter everywhere; 2 ranks too.
cat >"$tmp/build.yaml" <<'EOF2'
seed: 5
road: {length_m: 346000, speed_limit_mps: 24}
time: {duration_s: 3, dt_s: 0.1, output_interval_s: 0.5}
fleet:
  vehicles: 13000
  placement: random
  classes:
    - {class: midsize_sedan, fraction: 0.8}
    - {class: class8_tractor, fraction: 0.2}
  drivers:
    - {model: idm, count: 11700, noise_mps2: 0.2, heterogeneity: {spread: {T_s: 0.2, v0_mps: 0.1}}}
    - {model: pi_saturation, count: 1300}
initial: {state: equilibrium, jitter_m: 0.4, perturbation: {vehicle: 4352, dx_m: -1.5, dv_mps: -3}}
output: {trajectories: false}
EOF2
run "$tmp/build.yaml" -o "$tmp/build_ref.h5" --threads 1
mpi_same share_build_R3_threads1_block16 "$tmp/build_ref.h5" 3 1 16 "$tmp/build.yaml"
mpi_same share_build_R2_threads2_block1 "$tmp/build_ref.h5" 2 2 1 "$tmp/build.yaml"
# An overlap found by one rank alone, the same message as one process on every rank, exit status 2, no file:
# vehicle 9000 (rank 2's) pushed onto its leader; rank 1's first vehicle pushed back onto rank 0's last (4351), which
# only rank 0 sees, through the leader it builds.
for c in 9000:40:9000 4352:-40:4351; do
  IFS=: read -r pv dx who <<<"$c"
  name=share_build_error_vehicle$who
  want=$($BIN run "$tmp/build.yaml" -q -o "$tmp/bad.h5" --set initial.perturbation.vehicle=$pv \
         --set initial.perturbation.dx_m=$dx 2>&1); rc1=$?
  msg=$(mpi 3 run "$tmp/build.yaml" -q -o "$tmp/bad.h5" --set initial.perturbation.vehicle=$pv \
        --set initial.perturbation.dx_m=$dx 2>&1); rc=$?
  if [ $rc1 -eq 2 ] && [ $rc -eq 2 ] && echo "$want" | grep -q "vehicle $who overlap" &&
     [ "$(echo "$msg" | grep -c -F -- "$want")" -ge 1 ] && [ -z "$(ls "$tmp" | grep '^bad\.h5')" ]; then ok "$name"
  else ko "$name" "rc $rc1 / $rc: one process: $want; 3 ranks: $msg"; fi
  rm -f "$tmp"/bad.h5*
done

# A checkpoint of one process resumed on 3 ranks, each reading back only its share of the per-vehicle blocks and of
# the controllers' memory (12.5 MB for PI with saturation), in pieces of 64 KiB, all summed: the uninterrupted result;
# one byte changed in the last share's positions fails the checksum (exit status 2).
. tests/interrupt.sh
BLONG="$tmp/build.yaml --set time.duration_s=3000 --set time.output_interval_s=10"
run $BLONG -o "$tmp/blong_ref.h5" --threads 2
$BIN run $BLONG -q -o "$tmp/blong.h5" --threads 1 --checkpoint-every 0.2 >"$tmp/blong.log" 2>&1 & bpid=$!
if wait_checkpoint "$tmp/blong.h5" $bpid && signal_running TERM $bpid; then
  wait $bpid; rc=$?
  cp "$tmp/blong.h5.ckpt" "$tmp/bad_ckpt.h5.ckpt"; cp "$tmp/blong.h5.partial" "$tmp/bad_ckpt.h5.partial"
  $PY -c "import h5py,sys; d=h5py.File(sys.argv[1],'r+')['state/x']; d[d.shape[0]-5]^=1" "$tmp/bad_ckpt.h5.ckpt"
  MPI_TIMEOUT=400 mpi 3 run --resume "$tmp/blong.h5" -q --threads 1 >"$tmp/blong_r.log" 2>&1; rc2=$?
  if [ $rc -eq 3 ] && [ $rc2 -eq 0 ] && msg=$(same "$tmp/blong_ref.h5" "$tmp/blong.h5" 2>&1); then
    ok "share_resume_one_process_checkpoint_on_3_ranks ($msg)"
  else ko share_resume_one_process_checkpoint_on_3_ranks "rc $rc / $rc2: $(tail -3 "$tmp/blong_r.log") ${msg:-}"; fi
  msg=$(mpi 3 run --resume "$tmp/bad_ckpt.h5" -q --threads 1 2>&1); rc=$?
  if [ $rc -eq 2 ] && echo "$msg" | grep -q "does not match the contents"; then ok share_resume_checksum
  else ko share_resume_checksum "rc $rc: $msg"; fi
else
  ko share_resume_one_process_checkpoint_on_3_ranks "no checkpoint to interrupt: $(tail -3 "$tmp/blong.log")"
fi

# (b) Controllers: scenarios/sugiyama_followerstopper.yaml at 1536 vehicles (the same density, one AV in 24), and the
# ring of scenarios/ring_waves_av.yaml with 10 % PI with saturation (per-vehicle memory) under a Gipps safety filter
# whose interventions are counted.
FS="scenarios/sugiyama_followerstopper.yaml --set fleet.vehicles=1536 --set fleet.drivers[0].count=1472
    --set fleet.drivers[1].count=64 --set road.length_m=16058 --set time.duration_s=120 --set time.warmup_s=30
    --set output.trajectories=false"
PI="scenarios/ring_waves_av.yaml --set fleet.vehicles=1536 --set fleet.drivers[0].count=1382
    --set fleet.drivers[1].count=154 --set fleet.drivers[1].model=pi_saturation --set road.length_m=16058
    --set time.duration_s=120 --set time.warmup_s=30 --set fleet.drivers[1].safety.kind=gipps
    --set fleet.drivers[1].safety.gap_min_m=6"
run $FS -o "$tmp/fs_ref.h5" --threads 1
mpi_same followerstopper_R3_threads1_block16 "$tmp/fs_ref.h5" 3 1 16 $FS
run $PI -o "$tmp/pi_ref.h5" --threads 1
if $PY -c "import h5py,sys; n=h5py.File(sys.argv[1])['summary/safety_interventions'][()]; assert n > 100, n" "$tmp/pi_ref.h5"
then
  mpi_same pi_safety_R2_threads2_block16 "$tmp/pi_ref.h5" 2 2 16 $PI
  mpi_same pi_safety_R3_threads1_block1 "$tmp/pi_ref.h5" 3 1 1 $PI
else ko pi_safety "the reference run has no safety interventions: the check would not exercise the filter"; fi

# (c) Noise far beyond what the brakes absorb (tests/test_window.c): overlaps repaired in many windows, some of them
# at the ranks' boundaries.
cat >"$tmp/ov.yaml" <<'EOF'
seed: 7
road: {length_m: 36000}
time: {duration_s: 20, dt_s: 0.1, output_interval_s: 0.5}
fleet:
  vehicles: 3000
  classes: [{class: midsize_sedan, fraction: 1}]
  drivers: [{model: idm, fraction: 1, noise_mps2: 5, decel_max_mps2: 0.5}]
initial: {state: equilibrium}
output: {trajectories: false}
EOF
run "$tmp/ov.yaml" -o "$tmp/ov_ref.h5" --threads 2
if $PY -c "import h5py,sys; n=h5py.File(sys.argv[1])['timeseries/overlaps'][-1]; assert n > 50, n" "$tmp/ov_ref.h5"; then
  mpi_same overlaps_R2_threads2_block16 "$tmp/ov_ref.h5" 2 2 16 "$tmp/ov.yaml"
  mpi_same overlaps_R3_threads1_block16 "$tmp/ov_ref.h5" 3 1 16 "$tmp/ov.yaml"
else ko overlaps "the reference run repaired too few overlaps to exercise the repairs"; fi

# (d) A fault on rank 1: vehicle 900 of 1200 (5 blocks: rank 0 holds at most the first 768) returns NaN above 5 m/s
# (tests/data/nan_plugin.c): exit status 1, the message of one process (file names and program name aside), and the
# same partial file.
if cc -std=c11 -O1 -fPIC -shared -Iinclude tests/data/nan_plugin.c -o "$tmp/nan_plugin.so" -lm 2>"$tmp/cc.log"; then
  printf 'road: {length_m: 18000}\ntime: {duration_s: 60, dt_s: 0.1}\nfleet:\n  vehicles: 1200\n  classes: [{class: midsize_sedan, count: 1200}]\n  drivers:\n    - {model: idm, count: 1199}\n    - {model: plugin, path: nan_plugin.so, placement: explicit, indices: [900]}\ninitial: {state: rest}\n' >"$tmp/nan.yaml"
  $BIN run "$tmp/nan.yaml" -q -o "$tmp/nref.h5" --threads 1 2>"$tmp/nref.err"; r0=$?
  norm() { grep '^wavefuel' "$1" | sed -e "s#$2#FILE#g" -e 's#^wavefuel-mpi:#wavefuel:#'; }
  for bs in 16 1; do
    name=fault_on_rank1_R2_block$bs msg=
    mpi 2 run "$tmp/nan.yaml" -q -o "$tmp/n$bs.h5" --threads 1 --set time.block_steps=$bs 2>"$tmp/n$bs.err"; rc=$?
    if [ $r0 -eq 1 ] && [ $rc -eq 1 ] && grep -q "numerical fault at t = .*vehicle 900 " "$tmp/nref.err" &&
       [ "$(norm "$tmp/nref.err" "$tmp/nref.h5")" = "$(norm "$tmp/n$bs.err" "$tmp/n$bs.h5")" ] &&
       msg=$(same "$tmp/nref.h5.partial" "$tmp/n$bs.h5.partial" meta/reason meta/timeseries_rows 2>&1); then
      ok "$name ($msg)"
    else ko "$name" "rc $r0/$rc: $(norm "$tmp/nref.err" "$tmp/nref.h5") | $(norm "$tmp/n$bs.err" "$tmp/n$bs.h5") ${msg:-}"; fi
  done
else
  ko fault_on_rank1 "cannot build the test plugin: $(cat "$tmp/cc.log")"
fi

# SIGTERM once the ranks are stepping (rank 0 writes FILE.h5.partial before they step; checkpoints under MPI are
# written on a signal only), sent to mpirun and, in a second run, to rank 1 alone: every rank stops at the same step
# and rank 0 leaves FILE.h5.partial and .ckpt in the one-process format; the first resumed on 3 ranks, the second by
# `wavefuel run --resume`, both give the uninterrupted run. Open MPI 4.1's mpirun sends its ranks SIGCONT at once,
# SIGTERM odls_base_sigkill_timeout (1 s) later and SIGKILL 1 s after that: 3000 vehicles are saved well within it.
LONG="$tmp/het.yaml --set time.duration_s=6000 --set time.output_interval_s=1"
run $LONG -o "$tmp/long_ref.h5" --threads 2
alive() { local s; s=$(ps -o stat= -p "$1") && [ "${s:0:1}" != Z ]; } # a child ended but not waited for is a zombie
# rank_pid MPIRUN_PID R: the process of rank R (Open MPI names it in the environment of each rank).
rank_pid() {
  local k
  for k in $(pgrep -P "$1"); do tr '\0' '\n' <"/proc/$k/environ" 2>/dev/null | grep -qx "OMPI_COMM_WORLD_RANK=$2" && echo "$k"; done
}
# interrupted NAME TARGET SCENARIO...: runs the scenario on 2 ranks into $tmp/NAME.h5 and sends SIGTERM to TARGET
# (mpirun or rank1) once the ranks step; mpirun itself in the background (not under timeout, which would signal the
# ranks too), killed if it outlives 120 s. Sets rc to mpirun's exit status.
interrupted() {
  local name=$1 target=$2 pid to; shift 2
  mpirun -n 2 --oversubscribe --bind-to none "$MPIBIN" run "$@" -q -o "$tmp/$name.h5" --threads 1 >"$tmp/$name.log" 2>&1 &
  pid=$!; pids+=($pid)
  for _ in $(seq 600); do [ -e "$tmp/$name.h5.partial" ] && break; alive $pid || break; sleep 0.05; done
  sleep 1
  to=$pid; [ "$target" = rank1 ] && to=$(rank_pid $pid 1)
  kill -TERM ${to:-$pid} 2>/dev/null
  for _ in $(seq 1200); do alive $pid || break; sleep 0.1; done
  kill -KILL $pid 2>/dev/null; wait $pid; rc=$?
}
# stopped NAME STEPS: the partial and checkpoint of an interrupted run of STEPS steps (the steps done printed); no
# result.
stopped() {
  [ -e "$tmp/$1.h5.ckpt" ] && [ -e "$tmp/$1.h5.partial" ] && [ ! -e "$tmp/$1.h5" ] ||
    { echo "files: $(cd "$tmp" && echo "$1".h5*)"; return 1; }
  $PY -c "import h5py,sys; f=h5py.File(sys.argv[1]); s=f['meta/steps_done'][()]; \
assert f['meta/completed'][()]==0 and 0 < s < int(sys.argv[2]), s; print(s)" "$tmp/$1.h5.partial" "$2"
}
# sigterm_cases PREFIX STEPS REF SCENARIO...: the scenario (of STEPS steps) stopped by SIGTERM to mpirun leaves a
# checkpoint whose reason names the signal, resumed on 3 ranks; stopped by SIGTERM to rank 1 alone (exit status 3),
# resumed in one process; both equal REF.
sigterm_cases() {
  local p=$1 steps=$2 ref=$3 reason; shift 3
  interrupted "${p}i" mpirun "$@"
  if [ $rc -ne 0 ] && msg=$(stopped "${p}i" "$steps" 2>&1); then
    ok "${p}sigterm_to_mpirun_leaves_checkpoint (rc $rc, stopped after $msg steps)"
    reason=$($PY -c "import h5py,sys; print(h5py.File(sys.argv[1])['meta/reason'][()].decode())" "$tmp/${p}i.h5.partial")
    if [ "$reason" = "interrupted by SIGTERM" ] && grep -q "interrupted by SIGTERM at t = " "$tmp/${p}i.log"; then
      ok "${p}sigterm_named"
    else ko "${p}sigterm_named" "/meta/reason '$reason'; $(grep -m1 interrupted "$tmp/${p}i.log")"; fi
    MPI_TIMEOUT=400 mpi 3 run --resume "$tmp/${p}i.h5" -q --threads 1 >"$tmp/${p}ri.log" 2>&1; rc=$?
    if [ $rc -eq 0 ] && msg=$(same "$ref" "$tmp/${p}i.h5" 2>&1); then ok "${p}resume_on_3_ranks ($msg)"
    else ko "${p}resume_on_3_ranks" "rc $rc: $(tail -3 "$tmp/${p}ri.log") ${msg:-}"; fi
  else
    ko "${p}sigterm_to_mpirun_leaves_checkpoint" "rc $rc, ${msg:-}: $(tail -3 "$tmp/${p}i.log")"
  fi
  interrupted "${p}j" rank1 "$@"
  if [ $rc -eq 3 ] && msg=$(stopped "${p}j" "$steps" 2>&1); then
    ok "${p}sigterm_to_rank1_stops_all (rc $rc, stopped after $msg steps)"
    $BIN run --resume "$tmp/${p}j.h5" -q --threads 2 >"$tmp/${p}rj.log" 2>&1; rc=$?
    if [ $rc -eq 0 ] && msg=$(same "$ref" "$tmp/${p}j.h5" 2>&1); then ok "${p}resume_in_one_process ($msg)"
    else ko "${p}resume_in_one_process" "rc $rc: $(tail -3 "$tmp/${p}rj.log") ${msg:-}"; fi
  else
    ko "${p}sigterm_to_rank1_stops_all" "rc $rc (3: interrupted), ${msg:-}: $(tail -3 "$tmp/${p}j.log")"
  fi
}
sigterm_cases "" 60000 "$tmp/long_ref.h5" $LONG

# A checkpoint whose per-vehicle blocks span several chunks of the file (2.4 MB: 300 000 vehicles), saved by rank 0
# of 2 a share at a time (its pieces cross the chunks' edges) when a signal to rank 1 stops the run, resumed on 3
# ranks: the uninterrupted result.
BIG="bench/scaling/ring.yaml --set fleet.vehicles=300000 --set road.length_m=7500000 --set time.duration_s=200"
run $BIG -o "$tmp/big_ref.h5" --threads 2
interrupted big rank1 $BIG
if [ $rc -ne 0 ] && msg=$(stopped big 2000 2>&1); then
  MPI_TIMEOUT=400 mpi 3 run --resume "$tmp/big.h5" -q --threads 1 >"$tmp/big_r.log" 2>&1; rc=$?
  name=share_checkpoint_chunks_resume_on_3_ranks
  if [ $rc -eq 0 ] && msg=$(same "$tmp/big_ref.h5" "$tmp/big.h5" 2>&1); then ok "$name ($msg)"
  else ko $name "rc $rc: $(tail -3 "$tmp/big_r.log") ${msg:-}"; fi
else
  ko share_checkpoint_chunks_resume_on_3_ranks "not stopped: rc $rc, ${msg:-}: $(tail -3 "$tmp/big.log")"
fi

# (e) A corridor (tests/test_partition.c's): Poisson arrivals above capacity, noisy heterogeneous IDM, PI with
# saturation under a safety filter, two classes, grades, a headway and a speed-limit zone, a prescribed-speed virtual
# leader that drops; Edie cells of 250 m, so the ranks' segments are cut at 6000 m (2 ranks), 4000 and 8000 m (3),
# 3000, 6000 and 9000 m (4), with detectors at and beside the cuts.
cat >"$tmp/cor.yaml" <<'EOF'
seed: 17
road:
  type: corridor
  length_m: 12000
  speed_limit_mps: 30
  grade: {points: [[0, 0], [3000, 0.02], [7000, -0.015], [12000, 0]]}
  zones:
    - {type: headway, from_m: 2000, to_m: 4000, factor: 1.4}
    - {type: speed_limit, from_m: 9000, to_m: 9500, speed_limit_mps: 9}
time: {duration_s: 900, dt_s: 0.1, output_interval_s: 5.0, warmup_s: 450}
fleet:
  placement: random
  classes:
    - {class: midsize_sedan, fraction: 0.75}
    - {class: class8_tractor, fraction: 0.25}
  drivers:
    - {model: idm, fraction: 0.8, noise_mps2: 0.2, feasible_accel: clip,
       heterogeneity: {spread: {v0_mps: 0.1, T_s: 0.15}}}
    - {model: pi_saturation, fraction: 0.2, class: midsize_sedan, safety: {kind: gipps, gap_min_m: 4}}
corridor:
  inflow: {flow_vph: 2600, arrivals: poisson}
  outflow: {type: speed, points: [[0, 25], [350, 25], [400, 5], [700, 5], [750, 25]]}
  detectors: {x_m: [1000, 2998, 3000, 3990, 4000, 6000, 6003, 7995, 8000, 9000, 11900], interval_s: 60}
  edie: {dx_m: 250, dt_s: 30}
EOF
run "$tmp/cor.yaml" -o "$tmp/cor_ref.h5" --threads 1
for rt in "2 1" "2 2" "3 1" "4 1"; do
  set -- $rt
  mpi_same "corridor_R$1_threads$2" "$tmp/cor_ref.h5" "$1" "$2" 1 "$tmp/cor.yaml"
done

# (f) Noise far beyond what the brakes absorb, in queues behind slow zones that start past the cuts (tests/
# test_partition.c's): overlaps repaired along the road and between the ranks' vehicles, waves across the cuts.
cat >"$tmp/cov.yaml" <<'EOF'
seed: 5
road:
  type: corridor
  length_m: 6000
  zones:
    - {type: speed_limit, from_m: 2150, to_m: 2600, speed_limit_mps: 8}
    - {type: speed_limit, from_m: 3150, to_m: 3600, speed_limit_mps: 5}
    - {type: speed_limit, from_m: 4150, to_m: 4600, speed_limit_mps: 3}
time: {duration_s: 600, dt_s: 0.1, output_interval_s: 2.0}
fleet:
  classes: [{class: midsize_sedan, fraction: 1}]
  drivers: [{model: idm, fraction: 1, noise_mps2: 5, decel_max_mps2: 0.5}]
corridor:
  inflow: {flow_vph: 3000}
  outflow: {type: speed, points: [[0, 20], [200, 20], [260, 3], [600, 3]]}
  detectors: {x_m: [1995, 3000, 4001], interval_s: 30}
  edie: {dx_m: 500, dt_s: 20}
EOF
run "$tmp/cov.yaml" -o "$tmp/cov_ref.h5" --threads 2
if $PY -c "import h5py,sys; n=h5py.File(sys.argv[1])['timeseries/overlaps'][-1]; assert n > 50, n" "$tmp/cov_ref.h5"; then
  mpi_same corridor_overlaps_R2_threads2 "$tmp/cov_ref.h5" 2 2 1 "$tmp/cov.yaml"
  mpi_same corridor_overlaps_R3_threads1 "$tmp/cov_ref.h5" 3 1 1 "$tmp/cov.yaml"
else ko corridor_overlaps "the reference run repaired too few overlaps to exercise the repairs"; fi

# (g) A corridor long enough for two threads on a rank (more than 4096 vehicles on the entrance's segment by the end:
# the kernel's and the Edie measurement's threads): bench/corridor_vs_ring/corridor.yaml on 240 km, 2 ranks of 2
# threads against one process of 2.
BIGC="bench/corridor_vs_ring/corridor.yaml --set road.length_m=240000 --set time.duration_s=9000"
run $BIGC -o "$tmp/bigc_ref.h5" --threads 2
if $PY -c "import h5py,sys; n=h5py.File(sys.argv[1])['timeseries/vehicles'][-1]; assert n > 8000, n" "$tmp/bigc_ref.h5"
then mpi_same corridor_threads_R2_threads2 "$tmp/bigc_ref.h5" 2 2 1 $BIGC
else ko corridor_threads "the reference corridor holds too few vehicles for two threads on a rank"; fi

# (g2) A corridor in time-blocked windows (tests/test_partition.c's): a queue behind a leader that slows to 4 m/s,
# vehicles crossing the cuts (Edie cells of 500 m: 12 000 m; 8000 and 16 000 m; 6000, 12 000 and 18 000 m) and
# leaving inside windows of 16 steps, each rank behind the halo of the rank ahead; then noise beyond what the
# brakes absorb, so that windows overlap and are redone on every rank. Against one process stepping one step at a time.
cat >"$tmp/cwin.yaml" <<'EOF'
seed: 21
road:
  type: corridor
  length_m: 24000
  speed_limit_mps: 14
  grade: {points: [[0, 0], [9000, 0.01], [15000, -0.01], [24000, 0]]}
time: {duration_s: 1800, dt_s: 0.1, output_interval_s: 10.0, warmup_s: 600}
fleet:
  classes:
    - {class: midsize_sedan, fraction: 0.8}
    - {class: class8_tractor, fraction: 0.2}
  drivers:
    - {model: idm, fraction: 0.85, noise_mps2: 0.2, heterogeneity: {spread: {v0_mps: 0.1, T_s: 0.15}}}
    - {model: pi_saturation, fraction: 0.15, class: midsize_sedan, safety: {kind: gipps, gap_min_m: 4}}
corridor:
  inflow: {flow_vph: 3000, arrivals: poisson}
  outflow: {type: speed, points: [[0, 14], [100, 14], [200, 4], [1800, 4]]}
  detectors: {x_m: [3000, 7990, 8000, 11998, 12000, 12004, 16000, 16010, 20000], interval_s: 60}
  edie: {dx_m: 500, dt_s: 60}
EOF
run "$tmp/cwin.yaml" -o "$tmp/cwin_ref.h5" --threads 1
for rt in "2 2" "3 1" "4 1"; do
  set -- $rt
  mpi_same "corridor_windows_R$1_threads$2" "$tmp/cwin_ref.h5" "$1" "$2" 16 "$tmp/cwin.yaml"
done
NOISY="--set fleet.drivers[0].noise_mps2=3 --set fleet.drivers[0].decel_max_mps2=0.6"
run "$tmp/cwin.yaml" $NOISY -o "$tmp/cwin_noisy_ref.h5" --threads 1
mpi_same corridor_windows_overlaps_R3_threads1 "$tmp/cwin_noisy_ref.h5" 3 1 16 "$tmp/cwin.yaml" $NOISY

# (h) A corridor stopped by SIGTERM (to mpirun, to rank 1) resumes on 3 ranks and in one process to the
# uninterrupted result.
CLONG="$tmp/cor.yaml --set time.duration_s=30000"
run $CLONG -o "$tmp/clong_ref.h5" --threads 2
sigterm_cases corridor_ 300000 "$tmp/clong_ref.h5" $CLONG
# ... and in time-blocked windows (the queue of (g2), which stops inside its windows): a stop agreed at a window's end.
CWLONG="$tmp/cwin.yaml --set time.duration_s=30000 --set time.block_steps=16"
run $CWLONG -o "$tmp/cwlong_ref.h5" --threads 2
sigterm_cases corridor_windows_ 300000 "$tmp/cwlong_ref.h5" $CWLONG

# Refusals: exit status 2, the key or option named, no file; each case runs in one process (so it is the ranks that
# refuse it, not the scenario).
refused() { # name, text the message must hold, ranks, arguments of run (without -o)
  local name=$1 want=$2 r=$3 msg rc; shift 3
  if ! msg=$($BIN run "$@" -q --force -o "$tmp/one.h5" 2>&1); then ko "$name" "not a valid run in one process: $msg"; return; fi
  msg=$(mpi "$r" run "$@" -q -o "$tmp/bad.h5" 2>&1); rc=$?
  if [ $rc -eq 2 ] && echo "$msg" | grep -q -- "$want" && [ -z "$(ls "$tmp" | grep '^bad\.h5')" ]; then ok "$name"
  else ko "$name" "rc $rc, files: $(ls "$tmp" | grep '^bad\.h5' | tr '\n' ' '): $msg"; fi
  rm -f "$tmp"/bad.h5*
}
SHORT="$tmp/het.yaml --set time.duration_s=5"
refused refuses_lanes road.lanes 2 $SHORT --set road.lanes=2
for integ in cvode arkode rk4; do refused "refuses_$integ" time.integrator 2 $SHORT --set time.integrator=$integ; done
refused refuses_trajectories output.trajectories 2 $SHORT --set output.trajectories=true
refused refuses_unfused time.fused_step 2 $SHORT --set time.fused_step=false
sed "s#network: data/#network: $PWD/scenarios/data/#" scenarios/sugiyama_mlp.yaml >"$tmp/learned.yaml"
refused refuses_mlp mlp 2 "$tmp/learned.yaml" --set fleet.vehicles=1536 --set 'fleet.drivers[0].count=1472' \
  --set 'fleet.drivers[1].count=64' --set road.length_m=16058 --set output.trajectories=false \
  --set time.duration_s=5 --set time.warmup_s=0
refused refuses_external external 2 scenarios/ring_waves_av.yaml --set fleet.vehicles=1536 \
  --set 'fleet.drivers[0].count=1382' --set 'fleet.drivers[1].count=154' --set 'fleet.drivers[1].model=external' \
  --set road.length_m=16058 --set time.duration_s=5 --set time.warmup_s=0
refused refuses_checkpoint_every --checkpoint-every 2 $SHORT --checkpoint-every 1
# 700 vehicles on 2 ranks: 3 blocks, one for rank 0.
refused refuses_too_few_per_rank fleet.vehicles 2 $SHORT --set fleet.vehicles=700
CSHORT="$tmp/cor.yaml --set time.duration_s=60 --set time.warmup_s=0"
refused corridor_refuses_lanes road.lanes 2 scenarios/corridor_bottleneck_lanes.yaml --set time.duration_s=60 \
  --set time.warmup_s=0
refused corridor_refuses_trajectories output.trajectories 2 tests/data/tiny_corridor.yaml --set time.duration_s=40
refused corridor_refuses_unfused time.fused_step 2 $CSHORT --set time.fused_step=false
refused corridor_refuses_external external 2 $CSHORT --set 'fleet.drivers[1].model=external'
# 12 km in Edie cells of 3 km: 4 cells, fewer than 5 ranks
refused corridor_refuses_short_segments corridor.edie.dx_m 5 $CSHORT --set corridor.edie.dx_m=3000

# Uneven shares, refused or run as one process runs them: windows on some ranks and single steps on others would
# exchange halos of different sizes. 1000 vehicles on 2 ranks: rank 1 holds a whole block and 232 vehicles (fewer
# than 512); 8960 vehicles (35 blocks) on 2 ranks of 9 threads: 17 blocks on rank 0, 18 on rank 1, which alone has
# two per thread.
refused_or_same() { # name, ranks, threads, arguments of run (without -o)
  local name=$1 r=$2 th=$3 msg rc; shift 3
  run "$@" -o "$tmp/u_ref.h5" --threads 1
  msg=$(mpi "$r" run "$@" -q -o "$tmp/u.h5" --threads "$th" 2>&1); rc=$?
  if [ $rc -eq 2 ] && echo "$msg" | grep -q fleet.vehicles && [ -z "$(ls "$tmp" | grep '^u\.h5')" ]; then ok "$name (refused)"
  elif [ $rc -eq 0 ] && msg=$(same "$tmp/u_ref.h5" "$tmp/u.h5" 2>&1); then ok "$name ($msg)"
  else ko "$name" "rc $rc, files: $(ls "$tmp" | grep '^u\.h5' | tr '\n' ' '): $(echo "$msg" | grep -m3 'MPI_ERR\|wavefuel')"; fi
  rm -f "$tmp"/u.h5* "$tmp/u_ref.h5"
}
refused_or_same short_last_share_R2 2 1 $SHORT --set fleet.vehicles=1000
refused_or_same window_fits_one_rank_R2_threads9 2 9 "$tmp/ov.yaml" --set fleet.vehicles=8960 \
  --set road.length_m=240000 --set 'fleet.drivers[0].noise_mps2=0.3' --set time.duration_s=5
