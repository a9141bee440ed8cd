# The commands a new user runs. `make test` works on a fresh Debian bookworm machine: it installs the Debian
# packages (deploy/install-deps.sh), configures, builds, and runs every test, fuzzers included.
BUILD      ?= build
FUZZ_BUILD ?= build-fuzz
JOBS       ?= $(shell nproc)
# Seconds each fuzz target runs: briefly under `make test`, longer under `make fuzz`.
FUZZ_SECONDS ?= 20
FUZZ_LONG_SECONDS ?= 600
SERVE_DATA ?= $(firstword $(wildcard data/*.tfrecord* data/*.json) ../shared/data/womd/tfrecord)

.PHONY: all deps build test unit-test fuzz-build fuzz serve clean

all: build

deps:
	./deploy/install-deps.sh

build: deps
	cmake -S . -B $(BUILD) -G Ninja
	cmake --build $(BUILD) -j $(JOBS)

fuzz-build: deps
	CC=clang CXX=clang++ cmake -S . -B $(FUZZ_BUILD) -G Ninja -DSCENESTREAMER_FUZZ=ON -DFUZZ_SECONDS=$(FUZZ_SECONDS)
	cmake --build $(FUZZ_BUILD) -j $(JOBS)

unit-test: build
	ctest --test-dir $(BUILD) --output-on-failure -j $(JOBS)

test: unit-test fuzz-build
	ctest --test-dir $(FUZZ_BUILD) --output-on-failure

fuzz:
	$(MAKE) fuzz-build FUZZ_SECONDS=$(FUZZ_LONG_SECONDS)
	ctest --test-dir $(FUZZ_BUILD) --output-on-failure

# The gRPC server with its defaults: the bundled model (or random weights, loudly), the bundled scenarios, port 50051.
serve: build
	$(BUILD)/server/scenestreamer-server

clean:
	rm -rf $(BUILD) $(FUZZ_BUILD)
