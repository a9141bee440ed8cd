#!/bin/sh
# Installs every Debian package the project needs: the one list (the Makefile and the Dockerfile both call this).
# Idempotent: packages already installed are not fetched again, and `apt-get update` runs at most once per call,
# only when something is missing. Runs as root, or through sudo otherwise.
set -eu

PACKAGES="
  build-essential cmake ninja-build pkg-config git
  clang libclang-rt-14-dev
  protobuf-compiler libprotobuf-dev
  libgrpc++-dev libgrpc-dev protobuf-compiler-grpc
  libeigen3-dev libabsl-dev libspdlog-dev nlohmann-json3-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  python3-grpcio python3-protobuf
  python3-numpy python3-setuptools python3-wheel python3-venv
  sumo sumo-tools
  librsvg2-bin
  nginx
  libtorch-dev libopenblas0-openmp
"
# python3-numpy, -setuptools, -wheel and -venv: the Python package (python/), its build and its install test.
# libtorch-dev and libopenblas0-openmp join this list with the trainer (training/), which is the only part that needs
# them: they pull in ~330 shared libraries.

missing=""
for p in $PACKAGES; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing="$missing $p"
  fi
done

if [ -z "$missing" ]; then
  echo "install-deps: all packages present"
  exit 0
fi

if [ "$(id -u)" -eq 0 ]; then SUDO=""; else SUDO="sudo"; fi
echo "install-deps: installing$missing"
$SUDO apt-get update -q
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends $missing
