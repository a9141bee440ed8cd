# The commands a new user runs. `make test` works on a fresh Debian bookworm machine: it installs the Debian
# packages (deploy/install-deps.sh), configures, builds, and runs every test, fuzzers included.
BUILD      ?= build
FUZZ_BUILD ?= build-fuzz
JOBS       ?= $(shell nproc)
# Seconds each fuzz target runs: briefly under `make test`, longer under `make fuzz`.
FUZZ_SECONDS ?= 20
FUZZ_LONG_SECONDS ?= 600
# The CMake options of every build: `make build` and the image's build stage (Dockerfile; tests/deploy checks it).
CMAKE_OPTIONS = -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo
SERVE_DATA ?= $(firstword $(wildcard data/*.tfrecord* data/*.json) ../shared/data/womd/tfrecord)

.PHONY: all deps build test unit-test determinism fuzz-build fuzz serve clean train-default image image-test soak

all: build

deps:
	./deploy/install-deps.sh

build: deps
	cmake -S . -B $(BUILD) $(CMAKE_OPTIONS)
	cmake --build $(BUILD) -j $(JOBS)

fuzz-build: deps
	CC=clang CXX=clang++ cmake -S . -B $(FUZZ_BUILD) -G Ninja -DSCENESTREAMER_FUZZ=ON -DFUZZ_SECONDS=$(FUZZ_SECONDS)
	cmake --build $(FUZZ_BUILD) -j $(JOBS)

unit-test: build
	ctest --test-dir $(BUILD) --output-on-failure -j $(JOBS)

test: unit-test fuzz-build
	ctest --test-dir $(FUZZ_BUILD) --output-on-failure

# The RNG and the rollout-comparing session tests again in a Debug build (tests/determinism/debug_build.sh): a cold
# -O0 build of the engine takes longer than the rest of `make test`, so it has a target of its own.
determinism: build
	ctest --test-dir $(BUILD) -C determinism -R '^determinism\.' --output-on-failure

fuzz:
	$(MAKE) fuzz-build FUZZ_SECONDS=$(FUZZ_LONG_SECONDS)
	ctest --test-dir $(FUZZ_BUILD) --output-on-failure

# The gRPC server with its defaults: the bundled model (or random weights, loudly), the bundled scenarios, port 50051.
serve: build
	$(BUILD)/server/scenestreamer-server

# The container image (Dockerfile) built with buildah, no registry needed: the debian:bookworm base is made by
# debootstrap from the Debian archive apt uses (deploy/image/debian-base.sh). IMAGE_NATIVE=ON builds for this CPU.
IMAGE        ?= localhost/scenestreamer:latest
IMAGE_NATIVE ?= OFF
image:
	./deploy/install-deps.sh image
	./deploy/image/debian-base.sh
	buildah bud --isolation chroot --layers --pull=never --format docker --build-arg NATIVE=$(IMAGE_NATIVE) \
	  -t $(IMAGE) .

# The image's server (buildah run, host network, a loopback port) driven by the load generator and the image's own
# health probe.
image-test: build
	./deploy/image/image-test.sh $(IMAGE) $(BUILD)/client_examples/scenestreamer-load

# 30 minutes of steady load through the router on 3 loopback replicas (tests/integration/cluster_soak.py).
SOAK_MINUTES ?= 30
soak: build
	SS_SOAK_MINUTES=$(SOAK_MINUTES) ctest --test-dir $(BUILD) -C soak -R '^integration.cluster_soak$$' -V

# The default model (models/default.safetensors), reproduced from scratch: 300 SUMO scenarios, then the trainer on
# the real train split plus them (hours on 2 cores; stop it any time and run it again: it resumes from its
# checkpoint). The run lives outside the repository. TRAIN_FROM_COMMITTED=1 starts from the committed checkpoint
# (models/train-checkpoint.pt) instead, to continue the run the committed model came from: raise TRAIN_STEPS past the
# checkpoint's step (the committed checkpoint is step 3,500, with TRAIN_AGENTS=64). The committed run used these
# flags with 1,550 steps from step 788 to 1,550, then 2,500 (a warm restart), then from 2,500 with 64 agents and
# 4,000 and 3,500 steps, to the end at 3,500; its first 788 steps ran under longer schedules (docs/model.md). From scratch, these defaults make a model close to step 2,500's.
WOMD       ?= ../shared/data/womd
TRAIN_DIR  ?= $(HOME)/.cache/scenestreamer/train-default
TRAIN_STEPS  ?= 2500
TRAIN_AGENTS ?= 32
TRAIN_FLAGS = --config small --data $(WOMD)/json/train --synthetic $(TRAIN_DIR)/sumo,data --val $(WOMD)/json/val \
  --real-fraction 0.7 --steps $(TRAIN_STEPS) --stage1-steps 900 --batch 4 --lr 5e-4 --warmup 150 --max-agents $(TRAIN_AGENTS) \
  --max-map-segments 1500 --threads 1 --val-every 200 --val-scenarios 16 --checkpoint-every 50 \
  --eval-every 500 --eval-tool $(BUILD)/tools/scenestreamer --eval-scenarios 8

train-default: build
	test -f $(TRAIN_DIR)/sumo/MANIFEST || $(BUILD)/tools/scenestreamer dataset sumo --out $(TRAIN_DIR)/sumo \
	  --scenarios 300 --seed 7 --workers 1
	mkdir -p $(TRAIN_DIR)/run
	if [ "$(TRAIN_FROM_COMMITTED)" = 1 ] && [ ! -f $(TRAIN_DIR)/run/checkpoint.pt ]; then \
	  cp models/train-checkpoint.pt $(TRAIN_DIR)/run/checkpoint.pt; fi
	OMP_WAIT_POLICY=PASSIVE nice -n 10 $(BUILD)/training/scenestreamer-train $(TRAIN_FLAGS) --out $(TRAIN_DIR)/run --resume
	$(BUILD)/training/scenestreamer-train export --checkpoint $(TRAIN_DIR)/run/checkpoint.pt --out models/default.safetensors
	$(BUILD)/training/scenestreamer-train plot --run $(TRAIN_DIR)/run --out models/loss_curves.svg

clean:
	rm -rf $(BUILD) $(FUZZ_BUILD)
