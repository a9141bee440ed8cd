#!/bin/sh
# scenestreamer bench --json, as a user runs it (small model, few steps so that it is quick): the JSON object the
# issue specifies, with figures that make sense. It checks the contract and the arithmetic, not the speed.
# usage: bench_test.sh SCENESTREAMER DATA_DIR
set -eu
bin=$1
data=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
scenario="$data/womd/tfrecord/motion_data_one_scenario.tfrecord"

"$bin" bench --json --model small --scenario "$scenario" --steps 3 --long-steps 25 > "$tmp/bench.json"
/usr/bin/python3 - "$tmp/bench.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
counts = ["16", "32", "64", "128"]
for key in ["step_ms_p50", "step_ms_p99", "step_gflop", "step_gflops_achieved", "step_ms_at_gemm_peak"]:
    assert sorted(r[key], key=int) == counts, (key, r[key])
    assert all(r[key][n] > 0 for n in counts), (key, r[key])
assert all(r["step_ms_p99"][n] >= r["step_ms_p50"][n] for n in counts), r
# More agents, more work: the decoder's own count grows with the agent count.
gflop = [r["step_gflop"][n] for n in counts]
assert gflop == sorted(gflop) and gflop[-1] > 3 * gflop[0], gflop
assert r["gemm_gflops"] > 0
for n in counts:  # the floor is the counted work at the measured GEMM rate
    assert abs(r["step_ms_at_gemm_peak"][n] - r["step_gflop"][n] / r["gemm_gflops"] * 1e3) < 1e-6, n
assert r["cached_vs_full_ratio"] > 1, r["cached_vs_full_ratio"]
# The 64-agent step again with two threads in the step (the same session): its time and the ratio to one thread.
t2 = r["step_ms_p50_2_threads"]["64"]
assert t2 > 0 and abs(r["step_2_threads_speedup"]["64"] - r["step_ms_p50"]["64"] / t2) < 1e-9, r
# small: 4 layers of d 64, K and V, in half floats by default
assert r["kv_precision"] == "fp16", r["kv_precision"]
assert r["kv_bytes_per_token"] == 2 * 4 * 64 * 2, r["kv_bytes_per_token"]
bf16 = "avx512_bf16" in open("/proc/cpuinfo").read().split()
assert r["matmul_precision"] == ("bf16" if bf16 else "fp32"), r
assert r["session_bytes_after_25_steps"] > 0 and r["session_bytes_after_window"] > 0
assert r["session_bytes_after_1000_steps"] is None  # not measured with --long-steps 25, and says so
assert r["lights"] == 16 and r["map_segments"] > 0 and r["model"] == "small"
PY

"$bin" bench --json --model small --scenario "$scenario" --steps 1 --long-steps 1 --kv-precision fp32 > "$tmp/f32.json"
/usr/bin/python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); assert r["kv_precision"]=="fp32" and r["kv_bytes_per_token"]==2*4*64*4, r' "$tmp/f32.json"

# bf16 products where the CPU has AVX512-BF16 (flags in /proc/cpuinfo), on AMX where it has that too; a clear error
# where it has not.
if grep -qw avx512_bf16 /proc/cpuinfo; then
  kernel=avx512-bf16
  grep -qw amx_bf16 /proc/cpuinfo && kernel=amx
  "$bin" bench --json --model small --scenario "$scenario" --steps 1 --long-steps 1 --matmul-precision bf16 > "$tmp/b16.json"
  /usr/bin/python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); assert r["matmul_precision"]=="bf16" and r["bf16_kernel"]==sys.argv[2] and r["step_ms_p50"]["64"] > 0, r' "$tmp/b16.json" "$kernel"
else
  if "$bin" bench --matmul-precision bf16 --steps 1 --long-steps 1 2> "$tmp/err"; then exit 1; fi
  grep -q "needs a CPU with AVX512-BF16" "$tmp/err"
fi

# Errors name what was wrong.
if "$bin" bench --steps zero 2> "$tmp/err"; then exit 1; fi
grep -q -- "--steps: Illegal value 'zero'" "$tmp/err"
if "$bin" bench --model nope.safetensors --steps 1 2> "$tmp/err"; then exit 1; fi
grep -q "nope" "$tmp/err"
if "$bin" bench --kv-precision bf16 --steps 1 2> "$tmp/err"; then exit 1; fi
grep -q "unknown KV precision 'bf16'" "$tmp/err"
if "$bin" bench --matmul-precision fp16 --steps 1 2> "$tmp/err"; then exit 1; fi
grep -q "unknown matmul precision 'fp16'" "$tmp/err"
echo "bench_test: ok"
