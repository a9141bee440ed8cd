# The SceneStreamer server image: built here with `make image` (buildah, no registry needed; see README "Deployment"),
# and with any Dockerfile builder elsewhere:
#   docker build -t scenestreamer .                      portable x86-64-v3 (the default)
#   docker build --build-arg NATIVE=ON -t scenestreamer . for the build host's CPU only (AVX-512 kernels where present)
# Both stages install from deploy/install-deps.sh, the project's one package list (its build and runtime sets).

# ---- build: the server and its health probe, with the Makefile's CMake options ----
FROM debian:bookworm AS build
COPY deploy/install-deps.sh /src/deploy/install-deps.sh
RUN /src/deploy/install-deps.sh build && rm -rf /var/lib/apt/lists/*
# Only what CMake reads: a new model or new scenarios (final stage) leave the compiled layers cached.
COPY CMakeLists.txt /src/
COPY proto /src/proto
COPY engine /src/engine
COPY server /src/server
COPY client_examples /src/client_examples
COPY tools /src/tools
COPY training /src/training
COPY bench /src/bench
COPY tests /src/tests
COPY python /src/python
WORKDIR /src
# ON: -march=native (only for hosts like the build machine); OFF: -march=x86-64-v3, runs on any AVX2 x86-64.
ARG NATIVE=OFF
RUN cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSCENESTREAMER_NATIVE=${NATIVE} \
 && cmake --build build --target scenestreamer-server scenestreamer-health \
 && strip build/server/scenestreamer-server build/client_examples/scenestreamer-health

# ---- the image: run-time libraries, two binaries, the bundled scenarios and model ----
FROM debian:bookworm
COPY deploy/install-deps.sh /tmp/install-deps.sh
RUN /tmp/install-deps.sh runtime && rm -rf /var/lib/apt/lists/* /tmp/install-deps.sh \
 && groupadd --system --gid 10001 scenestreamer \
 && useradd --system --uid 10001 --gid 10001 --home-dir /srv/scenestreamer --create-home scenestreamer
WORKDIR /srv/scenestreamer
COPY --from=build /src/build/server/scenestreamer-server /src/build/client_examples/scenestreamer-health \
     /usr/local/bin/
# The server looks for models/*.safetensors and data/ in its working directory. models/ holds the model card and,
# once a trained model ships, its weights (.dockerignore keeps the training checkpoint out); without weights the
# server serves random ones and says so loudly.
COPY data/ data/
COPY models/ models/
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
