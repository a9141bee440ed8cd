#!/bin/sh
# Installs every Debian package the project needs: the one list (the Makefile and the Dockerfile both call this).
# Idempotent: packages already installed are not fetched again, and `apt-get update` runs at most once per call,
# only when something is missing. Runs as root, or through sudo otherwise.
#   deploy/install-deps.sh           everything: build, tests, tools, trainer (what `make` uses)
#   deploy/install-deps.sh build     what compiling the server and its clients needs (the image's build stage)
#   deploy/install-deps.sh runtime   the shared libraries the server and its probe load (the image's final stage)
#   deploy/install-deps.sh image     what `make image` needs on the host (buildah, debootstrap)
set -eu

# The server's and the health probe's run-time libraries (their other dependencies come with these).
RUNTIME="libgrpc++1.51 libprotobuf32 libabsl20220623 libspdlog1.10 libprometheus-cpp-pull1.0 libjemalloc2 libhiredis0.14"
# CMake configures the whole tree (tests and benchmarks too), so their headers are part of a build.
BUILD="
  build-essential cmake ninja-build pkg-config
  protobuf-compiler libprotobuf-dev
  libgrpc++-dev libgrpc-dev protobuf-compiler-grpc libssl-dev openssl
  libeigen3-dev libabsl-dev libspdlog-dev nlohmann-json3-dev prometheus-cpp-dev libjemalloc-dev libcivetweb-dev
  libhiredis-dev
  libgtest-dev libgmock-dev libbenchmark-dev
"
ALL="$BUILD
  git
  clang libclang-rt-14-dev
  python3-grpcio python3-protobuf
  python3-numpy python3-setuptools python3-wheel python3-venv
  sumo sumo-tools
  librsvg2-bin
  nginx haproxy yamllint python3-yaml
  redis-server
  libtorch-dev libopenblas0-openmp
  python3-torch
  chromium
"
# libjemalloc-dev: the allocator of the server and the tools (server/allocator.h), linked in place of glibc's malloc.
# python3-numpy, -setuptools, -wheel and -venv: the Python package (python/), its build and its install test.
# libtorch-dev and libopenblas0-openmp join this list with the trainer (training/), which is the only part that needs
# them: they pull in ~330 shared libraries. python3-torch (on top of libtorch): the PPO example
# (client_examples/python/ppo.py) and its test. nginx and haproxy are the session-affine routers (deploy/router/), run by
# the cluster test; yamllint checks deploy/k8s/.
# libhiredis-dev (libhiredis0.14 at run time): the server's client of the shared session store (server/session_store.h);
# redis-server: that store, which the cluster tests start on loopback (tests/integration/redis_process.py).
# libcivetweb-dev: the viewer's HTTP and WebSocket server (viewer/). chromium: the viewer's browser tests
# (tests/viewer), driven by playwright-core from npm (the npm step at the end).
IMAGE="buildah debootstrap"

case "${1:-all}" in
  all) PACKAGES="$ALL" ;;
  build) PACKAGES="$BUILD" ;;
  runtime) PACKAGES="$RUNTIME" ;;
  image) PACKAGES="$IMAGE" ;;
  *) echo "install-deps: unknown set '$1' (all, build, runtime, image)" >&2; exit 2 ;;
esac

missing=""
for p in $PACKAGES; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing="$missing $p"
  fi
done

if [ -z "$missing" ]; then
  echo "install-deps: all packages present"
else
  if [ "$(id -u)" -eq 0 ]; then SUDO=""; else SUDO="sudo"; fi
  echo "install-deps: installing$missing"
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends $missing
fi

# The viewer's page tools from the npm registry (viewer/web/package-lock.json): Vite and TypeScript build the page
# (its build, viewer/web/dist, is committed, so compiling needs no Node.js), playwright-core drives chromium in the
# browser tests. Only for the full set; `npm ci` runs again only when the lockfile changed. They need Node.js 20.19
# or newer (Vite 7); Debian bookworm's nodejs is 18, so the machine's own Node.js is used.
if [ "${1:-all}" = all ]; then
  WEB="$(cd "$(dirname "$0")/.." && pwd)/viewer/web"
  if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
    echo "install-deps: the viewer's page tools need Node.js 20.19 or newer and npm on PATH (Debian bookworm's" \
         "nodejs 18 is too old for Vite 7)" >&2
    exit 1
  fi
  if ! node -e 'const [a, b] = process.versions.node.split(".").map(Number); process.exit(a > 20 || (a === 20 && b >= 19) ? 0 : 1)'; then
    echo "install-deps: Node.js $(node --version) is older than 20.19, which the viewer's page tools (Vite 7) need" >&2
    exit 1
  fi
  if ! cmp -s "$WEB/package-lock.json" "$WEB/node_modules/.package-lock.json.installed" 2>/dev/null; then
    echo "install-deps: npm ci in viewer/web"
    (cd "$WEB" && npm ci --no-audit --no-fund) && cp "$WEB/package-lock.json" "$WEB/node_modules/.package-lock.json.installed"
  fi
fi
