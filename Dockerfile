# The SceneStreamer server image: built here with `make image` (buildah, no registry needed; see README "Deployment"),
# and with any Dockerfile builder elsewhere:
#   docker build -t scenestreamer .                      portable x86-64-v3 (the default)
#   docker build --build-arg NATIVE=ON -t scenestreamer . for the build host's CPU only (AVX-512 kernels where present)
# The build stage and the image install packages from deploy/install-deps.sh, the project's one package list (its
# build and runtime sets); the binaries and the bundled files come from the install target (`cmake --install`).

# ---- build: the server and its health probe, with the Makefile's CMake options, installed by the install target's
# server component (cmake --install; into /install, the image's /usr/local) ----
FROM debian:bookworm AS build
COPY deploy/install-deps.sh /src/deploy/install-deps.sh
RUN /src/deploy/install-deps.sh build && rm -rf /var/lib/apt/lists/*
# Only what CMake reads: a new model or new scenarios (the share stage) leave the compiled layers cached.
COPY CMakeLists.txt /src/
COPY proto /src/proto
COPY common /src/common
COPY engine /src/engine
COPY offline /src/offline
COPY server /src/server
COPY client_examples /src/client_examples
COPY tools /src/tools
COPY training /src/training
COPY bench /src/bench
COPY tests /src/tests
COPY python /src/python
COPY viewer /src/viewer
WORKDIR /src
# ON: -march=native (only for hosts like the build machine); OFF: -march=x86-64-v3, runs on any AVX2 x86-64.
ARG NATIVE=OFF
RUN cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSCENESTREAMER_NATIVE=${NATIVE} \
 && cmake --build build --target scenestreamer-server scenestreamer-health \
 && DESTDIR=/install cmake --install build --prefix /usr/local --component server --strip

# ---- share: the bundled model, its card and the sample scenarios, installed by the share component beside the
# binaries (/usr/local/share/scenestreamer, where the server finds them from its own path) ----
FROM build AS share
COPY data/ /src/data/
COPY models/ /src/models/
COPY docs/model.md /src/docs/model.md
RUN DESTDIR=/install cmake --install build --prefix /usr/local --component share

# ---- the image: run-time libraries, the installed tree (two binaries, the bundled model and scenarios) ----
FROM debian:bookworm
COPY deploy/install-deps.sh /tmp/install-deps.sh
RUN /tmp/install-deps.sh runtime && rm -rf /var/lib/apt/lists/* /tmp/install-deps.sh \
 && groupadd --system --gid 10001 scenestreamer \
 && useradd --system --uid 10001 --gid 10001 --home-dir /srv/scenestreamer --create-home scenestreamer
WORKDIR /srv/scenestreamer
# /usr/local/bin/scenestreamer-server and scenestreamer-health; /usr/local/share/scenestreamer/models (the default
# model and its card; .dockerignore keeps the training checkpoint out of the context) and .../data (the scenarios).
COPY --from=share /install/usr/local/ /usr/local/
RUN mkdir snapshots && chown scenestreamer:scenestreamer snapshots
VOLUME /srv/scenestreamer/snapshots
USER scenestreamer
EXPOSE 50051 9464
HEALTHCHECK --interval=10s --timeout=5s --start-period=60s --retries=3 \
  CMD ["scenestreamer-health", "--target", "127.0.0.1:50051"]
# All interfaces on purpose: in a container the port is reached from outside it (a bare server binds what --host
# says). SIGTERM drains and saves every session to the snapshot volume; the next start restores them.
ENTRYPOINT ["scenestreamer-server"]
CMD ["--host=0.0.0.0", "--port=50051", "--metrics_host=0.0.0.0", "--metrics_port=9464", \
     "--snapshot_dir=/srv/scenestreamer/snapshots"]
