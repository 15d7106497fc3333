#!/usr/bin/env bash
# Installs every Debian 12 package bisturi needs to build, run and test. Run as root (or with
# sudo). Idempotent: packages already present are left alone.
#   --bench-peers   also install the peer libraries the comparison benchmarks use (OpenMesh,
#                   CGAL, VTK)
set -euo pipefail

packages=(
  build-essential cmake g++ pkg-config
  ccache                             # compiler cache (CMake uses it when present)
  libglm-dev                         # vector maths (scene positions)
  libcli11-dev nlohmann-json3-dev    # command line, JSON reports
  libgtest-dev libgmock-dev          # tests
  clang libclang-rt-14-dev           # fuzz tests of the mesh readers (libFuzzer, sanitizers)
  libbenchmark-dev                   # benchmarks in tools/bench
  zlib1g-dev                         # gzip-encoded NRRD and .nii.gz volumes
  libgdcm-dev                        # DICOM series
  libosd-dev                         # subdivision surfaces (OpenSubdiv)
  libhidapi-dev libusb-1.0-0-dev     # device transports (hidapi, libusb)
  libembree-dev                      # collision BVH for soft tissue (sim/)
  libvulkan-dev mesa-vulkan-drivers  # stereo renderer (runtime/); lavapipe without a GPU
  glslang-tools glslc                # shaders/ to SPIR-V at build time
  vulkan-validationlayers            # the renderer's tests run with validation
  libopenxr-dev libpng-dev           # frame sinks: headset (OpenXR), headless (PNG)
  libtomlplusplus-dev libcairo2-dev  # scene files (TOML), session report plots
  slurm-wlm munge                    # the cohort test: a local Slurm cluster (tests/slurm)
)
if [[ "${1:-}" == "--bench-peers" ]]; then
  packages+=(libopenmesh-dev libcgal-dev libvtk9-dev)
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]} == 0)); then
  echo "install-deps: all ${#packages[@]} packages already installed"
  exit 0
fi
SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq -o DPkg::Lock::Timeout=600 \
  --no-install-recommends "${missing[@]}"
