#!/usr/bin/env bash
# Installs the Debian packages wavefuel needs to build, test and plot; the single place that lists them.
# As root: apt-get installs what is missing. Otherwise: prints the exact apt-get line and exits 1.
# Usage: tools/install-deps.sh [SET...]. No argument: the build/test/plot set. Optional sets, needed only by
# their make targets (so `make test` never requires them):
#   fuzz      clang + compiler-rt (libFuzzer, sanitizers) + LLVM libomp (Archer)  make fuzz, fuzz-smoke, tsan
#   valgrind  valgrind                                                           make valgrind
#   mpi       OpenMPI (mpicc, mpirun), parallel HDF5 (libhdf5-openmpi-dev)       make mpi (bin/wavefuel-mpi), bench/mpi_ring
#   rl        PyTorch, PyYAML (python3-torch, python3-yaml)                      examples/rl/ (training a policy)
#   sumo      SUMO, netconvert, Python traci and libsumo (sumo, sumo-tools)      bench/vs_sumo, bench/rl_envs
# libhdf5-dev brings both HDF5 libraries the build links: libhdf5 and the high-level libhdf5_hl (H5LT).
set -euo pipefail
PKGS=()
[ $# -eq 0 ] && set -- base
for set_name in "$@"; do
  case "$set_name" in
    base) PKGS+=(gcc make pkg-config libyaml-dev libhdf5-dev hdf5-tools libsundials-dev librandom123-dev liblapacke-dev libgsl-dev libsleef-dev
                 python3-h5py python3-numpy python3-matplotlib) ;;
    fuzz) PKGS+=(clang libclang-rt-14-dev libomp-14-dev) ;;
    valgrind) PKGS+=(valgrind) ;;
    mpi) PKGS+=(libopenmpi-dev openmpi-bin libhdf5-openmpi-dev) ;;
    rl) PKGS+=(python3-torch python3-yaml) ;;
    sumo) PKGS+=(sumo sumo-tools) ;;
    *) echo "install-deps.sh: unknown package set '$set_name' (base, fuzz, valgrind, mpi, rl, sumo)" >&2; exit 2 ;;
  esac
done
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
if [ "$(id -u)" -ne 0 ]; then
  echo "wavefuel: missing Debian packages. Run as root:" >&2
  echo "  apt-get update && apt-get install -y ${missing[*]}" >&2
  exit 1
fi
echo "wavefuel: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
