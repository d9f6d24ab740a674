#!/usr/bin/env bash
# A split corridor one step at a time against time-blocked windows, side by side in one run (docs/mpi.md, "Time-blocked
# windows"): the 200 km corridor of bench/corridor_vs_ring/corridor.yaml (about 5000 vehicles once full) on R ranks of
# one thread, time.block_steps 1, 16 and 64 in turn, REPEATS times; records every REC seconds (a window ends before
# each record step). BTL picks Open MPI's transport (vader,self: shared memory; tcp,self: TCP over loopback, dearer
# messages). Prints each run's loop wall time and vehicle-steps/s, then checks that the last runs' files are the same
# bits. Usage: [R=2] [REC=10] [BTL=vader,self] [REPEATS=3] bash bench/mpi_ring/corridor_windows.sh
set -eu
cd "$(dirname "$0")/../.."
export OMPI_MCA_btl=${BTL:-vader,self} OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_btl_vader_single_copy_mechanism=none OMPI_MCA_mpi_yield_when_idle=1
R=${R:-2} REC=${REC:-10} REPEATS=${REPEATS:-3}
tmp=$(mktemp -d /tmp/wf_corwin_XXXXXX)
trap 'rm -rf "$tmp"' EXIT
S="bench/corridor_vs_ring/corridor.yaml --set road.length_m=200000 --set time.duration_s=12000"
echo "# $(date -u +%FT%TZ) $(git rev-parse --short HEAD) R=$R btl=$OMPI_MCA_btl records every $REC s; load $(cut -d' ' -f1 /proc/loadavg)"
for rep in $(seq "$REPEATS"); do
  for b in 1 16 64; do
    mpirun -n "$R" --oversubscribe --bind-to none bin/wavefuel-mpi run $S --set time.output_interval_s="$REC" \
      --set time.block_steps=$b -o "$tmp/b$b.h5" --force --threads 1 -q >/dev/null
    /usr/bin/python3 -c "
import h5py, sys
f = h5py.File(sys.argv[1]); m = f['meta']; n = f['timeseries/vehicles'][()].mean()
print(f'block_steps {sys.argv[2]:>2}  repeat {sys.argv[3]}  loop {m[\"wall_time_s\"][()]:6.2f} s  N {n:.0f}  '
      f'{n * m[\"steps_done\"][()] / m[\"wall_time_s\"][()]:.3e} veh-steps/s')" "$tmp/b$b.h5" "$b" "$rep"
  done
done
/usr/bin/python3 tests/h5same.py "$tmp/b1.h5" "$tmp/b16.h5"
/usr/bin/python3 tests/h5same.py "$tmp/b1.h5" "$tmp/b64.h5"
