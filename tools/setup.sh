#!/usr/bin/env bash
# Installs every Debian package ignav needs to build, test and run.
# Idempotent: when everything is present it only checks and returns.
set -euo pipefail

packages=(
  # toolchain
  build-essential cmake ninja-build pkg-config clang-format
  # math, config, logging, CLI
  libeigen3-dev libyaml-cpp-dev nlohmann-json3-dev libspdlog-dev libfmt-dev libcli11-dev
  # images, point clouds, DICOM
  libopencv-dev libpcl-dev libdcmtk-dev dcmtk zlib1g-dev libpng-dev libdeflate-dev
  # the 3D view's surfaces (flying edges, windowed-sinc smoothing): VTK, which PCL brings too
  libvtk9-dev
  # ODE integration (Boost.Odeint, header-only) for the needle-deflection model
  libboost-dev
  # the seed plan's linear programme (GLPK's simplex)
  libglpk-dev
  # SHA-256 digests of motion plans (and DDS Security)
  libssl-dev
  # benchmarks: the reference DICOM converter and GNU time for peak memory
  dcm2niix time
  # 3D Slicer as a live client: the OpenIGTLink bridge (docs/OPENIGTLINK.md); expat reads
  # protocol 3's COMMAND XML
  libopenigtlink-dev libexpat1-dev
  # DDS
  cyclonedds-dev cyclonedds-tools
  # the service: sd_notify for the systemd unit, systemd-analyze and dpkg-shlibdeps for the
  # package's test (tools/package, tests/package)
  libsystemd-dev systemd dpkg-dev
  # the multi-host tests' network namespaces, veth pairs, bridge and router (tests/network);
  # ping measures the impaired link there
  iproute2 iputils-ping
  # tests and benchmarks (tshark: the DDS Security test captures the loopback)
  libgtest-dev libgmock-dev libbenchmark-dev tshark
  # fuzzing (libFuzzer ships with clang's runtime) and sanitizer symbolisation
  clang libclang-rt-14-dev llvm
  # ITK reads our .tfm files back in the tests (an independent reader)
  libinsighttoolkit5-dev
  # reference DICOM files for tests (pydicom ships real edge cases); the RT Structure Set
  # reader's independent references: dicompyler-core's volumes and plastimatch's rasterisation
  python3-pydicom python3-numpy python3-dicompylercore plastimatch
  # David Clunie's DICOM validator (dciodvfy): the RT Plan and RT Dose checked against the IODs
  dicom3tools
  # the web viewer's browser test: Debian's chromium, driven headless by playwright-core
  chromium fonts-dejavu-core
)
# The web viewer's app is built with node and npm (tools/ignav-web/app); a machine that has a
# newer Node.js of its own keeps it.
command -v node >/dev/null 2>&1 && command -v npm >/dev/null 2>&1 || packages+=(nodejs npm)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#packages[@]} packages present"
  exit 0
fi

echo "setup: installing ${#missing[@]} packages: ${missing[*]}"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
