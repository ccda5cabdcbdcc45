#!/usr/bin/env bash
# Installs the Debian packages rangex builds and runs with (idempotent, non-interactive).
# Nothing is downloaded at build time: every dependency is a system package.
set -euo pipefail

packages=(
  cmake ninja-build g++ pkg-config
  libyaml-cpp-dev libpng-dev libsqlite3-dev libeigen3-dev libceres-dev libopencv-dev
  libcpp-httplib-dev nlohmann-json3-dev libssl-dev openssl libspdlog-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  clang libclang-rt-14-dev clang-format
  libgrpc++-dev libprotobuf-dev protobuf-compiler protobuf-compiler-grpc
  glslang-tools libvulkan-dev mesa-vulkan-drivers
  ocl-icd-opencl-dev opencl-headers pocl-opencl-icd
  python3-statsmodels python3-grpcio python3-protobuf python3-yaml
  chromium chromium-driver python3-selenium python3-prometheus-client
  libaravis-dev libusb-1.0-0-dev aravis-tools iproute2 libmodbus-dev zlib1g-dev
  libpq-dev postgresql-15
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

sudo=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  sudo="sudo"
fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
