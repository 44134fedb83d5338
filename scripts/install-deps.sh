#!/usr/bin/env bash
# Installs fillgs's dependencies from Debian 12 packages. Idempotent: only packages that are
# not already installed are requested from apt.
#   scripts/install-deps.sh            what the build and the main job need (scripts/run.sh)
#   scripts/install-deps.sh --python   and the Python module's (pybind11, Python's headers, NumPy)
#   scripts/install-deps.sh --tests    and everything the tests and benchmarks use (scripts/test.sh)
set -euo pipefail

packages=(
  build-essential cmake pkg-config ninja-build
  libembree-dev            # Embree 3.13: ray-traced Gaussian proxies
  libopenvdb-dev           # OpenVDB: exploration grid
  libboost-iostreams-dev   # needed by OpenVDB's CMake module
  libeigen3-dev
  libopenimageio-dev
  openimageio-tools        # needed by OpenImageIO's CMake config
  python3-imath            # ships the PyImath library that Imath's CMake targets (pulled in by OpenImageIO) name; without it CMake warns
  libopencv-dev
  libtbb-dev
  nlohmann-json3-dev
  libhwy-dev               # Google Highway: portable SIMD with run-time dispatch
  libcli11-dev             # CLI11: the command line's flags, parsing and help
  zlib1g-dev               # zlib: deflated entries of .npz archives and .pth files
  colmap                   # COLMAP 3.8: triangulated initial points; a test round-trips the COLMAP export
  gnuplot-nox              # the plots (src/io/plot.cpp drives gnuplot through a pipe)
  libopenmpi-dev openmpi-bin  # observation tables over MPI ranks (fillgs observe --mpi)
)
python=(
  pybind11-dev python3-dev # the Python module (src/python)
  python3-numpy            # its arrays
  python3-pip python3-venv python3-setuptools python3-wheel  # `pip install --no-build-isolation .` (pyproject.toml, setup.py) into a venv
)
tests=(
  catch2                   # Catch2 2.13
  python3-torch            # PyTorch (CPU): tests/make_model_fixtures.py saves E-D3DGS, 4DGaussians and 4DGS models as their code does
  python3-pytest           # the Python module's tests (tests/python)
  clang libclang-rt-14-dev # the sanitizer + libFuzzer tree (scripts/build-fuzz.sh, tests/README.md, "Robustness")
  python3-openvdb          # the OpenVDB Python binding: a test opens exploration.vdb with it
  time                     # GNU time: the benchmarks read peak resident memory with it
)
for arg in "$@"; do
  case "$arg" in
    --python) packages+=("${python[@]}") ;;
    --tests) packages+=("${python[@]}" "${tests[@]}") ;;
    *) echo "install-deps: unknown option $arg (expected --python or --tests)" >&2; exit 2 ;;
  esac
done

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
