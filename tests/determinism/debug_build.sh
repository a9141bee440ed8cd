#!/bin/sh
# The determinism tests in a Debug build: a seed must give the same numbers without optimisation as with it (two
# classes named ss::Rng once made -O0 binaries draw another sequence). Configures a Debug build of just the RNG and
# session tests in <build>/debug-determinism (ccache when present), then runs the RNG's known-answer tests and the
# session tests that compare rollouts and are cheap enough without optimisation: a fork continuing like its source,
# and a 10 Hz session continuing identically after save/restore. (The engine at -O0 is tens of times slower: the
# same-seed rollout test alone ran more than 4 minutes, so it stays in the optimised build's suite.)
# usage: debug_build.sh <source dir> <build dir>
set -eu
src=$1
out=$2/debug-determinism
launcher=""
if command -v ccache > /dev/null; then
  launcher="-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache"
fi
# shellcheck disable=SC2086
cmake -S "$src" -B "$out" -G Ninja -DCMAKE_BUILD_TYPE=Debug $launcher > "$out.configure.log" 2>&1 ||
  { cat "$out.configure.log"; exit 1; }
cmake --build "$out" --target rng_test session_test > "$out.build.log" 2>&1 || { tail -50 "$out.build.log"; exit 1; }
"$out/tests/rng_test"
"$out/tests/session_test" --gtest_filter='*ForkCopies*:*TenHzPosesPushedBetweenSteps*'
