#!/usr/bin/env bash
# Build and run bench/mpi_ring/h5_write.c (one HDF5 file from R processes: gathered onto rank 0 against parallel
# HDF5), with Debian's parallel HDF5 (libhdf5-openmpi-dev) and Open MPI: `tools/install-deps.sh mpi` installs both.
# Usage: [N=10000000] [COLS=8] [REPEATS=3] [RANKS="2 4"] bash bench/mpi_ring/h5_write.sh
set -eu
cd "$(dirname "$0")/../.."
pkg-config --exists hdf5-openmpi || { echo "parallel HDF5 not installed (libhdf5-openmpi-dev)"; exit 1; }
tmp=$(mktemp -d /tmp/wf_h5w_XXXXXX)
trap 'rm -rf "$tmp"' EXIT
mpicc -O2 $(pkg-config --cflags hdf5-openmpi) bench/mpi_ring/h5_write.c $(pkg-config --libs hdf5-openmpi) -o "$tmp/h5_write"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
export OMPI_MCA_mpi_yield_when_idle=1
echo "# $(date -u +%FT%TZ) $(git rev-parse --short HEAD); files in $(df --output=source "$tmp" | tail -1) ($tmp)"
for r in ${RANKS:-2 4}; do
  mpirun -n "$r" --oversubscribe --bind-to none "$tmp/h5_write" "${N:-10000000}" "${COLS:-8}" "${REPEATS:-3}" "$tmp"
done
