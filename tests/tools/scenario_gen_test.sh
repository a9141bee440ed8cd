#!/bin/sh
# eval --protocol scenario-gen as a user runs it: the model (small random weights) places the log's counts and its
# scenes are written as a submission (every frame, box and type) and scored again from the files alone to the same
# numbers; the two baselines run; bad flags are refused naming what is wrong. Small: 3 real scenarios, 2 rollouts.
# usage: scenario_gen_test.sh SCENESTREAMER DATA_DIR
set -eu
bin=$1
data=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
set -- "$data/womd/tfrecord/motion_data_one_scenario.tfrecord" "$data/womd/json/val/womd_27d205cc.json" \
  "$data/womd/json/val/womd_d5b57279.json"

"$bin" init-weights --config small --seed 3 --out "$tmp/w.safetensors" > /dev/null
"$bin" eval --protocol scenario-gen --data "$@" --model "$tmp/w.safetensors" --rollouts 2 --seed 1 \
  --wosac-submission "$tmp/sub" --json "$tmp/direct.json" > "$tmp/direct.txt" 2> /dev/null
grep -q "counts exact in 6 of 6 rollouts" "$tmp/direct.txt"
test -s "$tmp/sub/submission.binproto-00000-of-00001"
"$bin" eval --protocol scenario-gen --data "$@" --submission "$tmp/sub" --json "$tmp/files.json" > /dev/null 2>&1
"$bin" eval --protocol scenario-gen --data "$@" --baseline log --rollouts 2 --json "$tmp/log.json" > /dev/null 2>&1
"$bin" eval --protocol scenario-gen --data "$@" --baseline placement --rollouts 2 --json "$tmp/placement.json" \
  > /dev/null 2>&1

/usr/bin/python3 - "$tmp" <<'PY'
import json, sys
tmp = sys.argv[1]
direct, files = (json.load(open(f"{tmp}/{n}.json")) for n in ("direct", "files"))
assert direct["realism"] == files["realism"], (direct["realism"], files["realism"])
assert direct["mmd_strict"] == files["mmd_strict"] and direct["mmd_relaxed"] == files["mmd_relaxed"]
for a, b in zip(direct["per_scenario"], files["per_scenario"]):
    assert a["realism"] == b["realism"], a["id"]
assert files["policy"] == "submission" and direct["policy"] == "model"
log, placement = (json.load(open(f"{tmp}/{n}.json")) for n in ("log", "placement"))
assert log["realism"]["meta"] > placement["realism"]["meta"], (log["realism"]["meta"], placement["realism"]["meta"])
assert placement["rollouts_with_exact_counts"] == 6
PY

expect_error() {  # expected message, then the command
  want=$1
  shift
  if "$@" > "$tmp/out.txt" 2>&1; then echo "accepted: $*" >&2; exit 1; fi
  grep -q -- "$want" "$tmp/out.txt" || { echo "no '$want' in:" >&2; cat "$tmp/out.txt" >&2; exit 1; }
}
expect_error "--mode full only" "$bin" eval --protocol scenario-gen --data "$1" --model "$tmp/w.safetensors" --mode motion --json "$tmp/x.json"
expect_error "is not log or placement" "$bin" eval --protocol scenario-gen --data "$1" --baseline cv --json "$tmp/x.json"
expect_error "is not wosac or scenario-gen" "$bin" eval --protocol what --data "$1" --baseline cv --json "$tmp/x.json"
expect_error "goes with --mode full" "$bin" simulate --scenario "$1" --model "$tmp/w.safetensors" --agent-counts 1,1,1 --out "$tmp/x.tfrecord"
expect_error "is not a count" "$bin" simulate --scenario "$1" --model "$tmp/w.safetensors" --mode full --agent-counts 1,x,1 --out "$tmp/x.tfrecord"
"$bin" simulate --scenario "$1" --model "$tmp/w.safetensors" --mode full --agent-counts 3,1,1 --steps 2 --out "$tmp/g.tfrecord" > "$tmp/sim.txt"
grep -q "6 agents at the end" "$tmp/sim.txt"
echo ok
