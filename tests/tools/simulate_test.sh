#!/bin/sh
# scenestreamer simulate, as a user runs it: random small weights, a real scenario, each mode, both --sdc rules, a
# 20 s scenario to its end; the rollout is a WOMD file that inspect and render read back.
# usage: simulate_test.sh SCENESTREAMER DATA_DIR
set -eu
bin=$1
data=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
scenario="$data/womd/tfrecord/motion_data_one_scenario.tfrecord"

"$bin" init-weights --config small --seed 3 --out "$tmp/w.safetensors" > /dev/null
for mode in motion full densify; do
  "$bin" simulate --scenario "$scenario" --model "$tmp/w.safetensors" --mode $mode --sdc log --steps 16 --seed 1 \
    --densify-target 60 --out "$tmp/$mode.tfrecord" > "$tmp/$mode.log"
  "$bin" inspect --json "$tmp/$mode.tfrecord" > "$tmp/$mode.json"
  /usr/bin/python3 - "$tmp/$mode.json" "$mode" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
assert r["frames"] == 81, r["frames"]             # 16 steps after the start: 17 model steps at 10 Hz
assert r["scenario_id"] == "637f20cafde22ff8-rollout", r["scenario_id"]
assert r["tracks"]["total"] >= 1, r["tracks"]
assert r["map_features"]["total"] == 301
assert r["sdc_track_index"] >= 0
PY
done
# --sdc model (the default): the model drives the SDC, which is still the rollout's SDC; by default the rollout runs
# to the scenario's last frame, whatever its length (91 frames: 16 steps; a 198-frame 20 s scenario: 38 steps).
"$bin" simulate --scenario "$scenario" --model "$tmp/w.safetensors" --seed 1 --out "$tmp/free.tfrecord" > "$tmp/free.log"
grep -q -- "--sdc model" "$tmp/free.log"
"$bin" simulate --scenario "$data/womd/json-20s/womd20s_92ddde4b.json" --model "$tmp/w.safetensors" --seed 1 \
  --out "$tmp/long.tfrecord" > /dev/null
"$bin" inspect --json "$tmp/free.tfrecord" > "$tmp/free.json"
"$bin" inspect --json "$tmp/long.tfrecord" > "$tmp/long.json"
/usr/bin/python3 - "$tmp" <<'PY'
import json, sys
free = json.load(open(sys.argv[1] + "/free.json"))
assert free["frames"] == 81 and free["sdc_track_index"] >= 0, (free["frames"], free["sdc_track_index"])
long = json.load(open(sys.argv[1] + "/long.json"))
assert long["frames"] == 191 and long["sdc_track_index"] >= 0, (long["frames"], long["sdc_track_index"])
PY
if cmp -s "$tmp/free.tfrecord" "$tmp/motion.tfrecord"; then echo "--sdc model and --sdc log gave the same rollout"; exit 1; fi
# The same seed gives the same file; another seed another.
"$bin" simulate --scenario "$scenario" --model "$tmp/w.safetensors" --mode full --sdc log --steps 16 --seed 1 \
  --out "$tmp/again.tfrecord" > /dev/null
cmp "$tmp/full.tfrecord" "$tmp/again.tfrecord"
"$bin" simulate --scenario "$scenario" --model "$tmp/w.safetensors" --mode full --sdc log --steps 16 --seed 2 \
  --out "$tmp/other.tfrecord" > /dev/null
if cmp -s "$tmp/full.tfrecord" "$tmp/other.tfrecord"; then echo "different seeds gave the same rollout"; exit 1; fi
"$bin" render "$tmp/motion.tfrecord" --animate --out "$tmp/motion.svg" > /dev/null
test -s "$tmp/motion.svg"

# Errors name what was wrong.
if "$bin" simulate --scenario "$scenario" --model "$tmp/nope" --out "$tmp/x.tfrecord" 2> "$tmp/err"; then exit 1; fi
grep -q "nope" "$tmp/err"
if "$bin" simulate --scenario "$scenario" --model "$tmp/w.safetensors" --mode fast --out "$tmp/x.tfrecord" 2> "$tmp/err"; then exit 1; fi
grep -q "fast" "$tmp/err"
if "$bin" simulate --scenario "$scenario" --model "$tmp/w.safetensors" --sdc ego --out "$tmp/x.tfrecord" 2> "$tmp/err"; then exit 1; fi
grep -q "ego" "$tmp/err"
if "$bin" simulate --scenario "$scenario" --model "$tmp/w.safetensors" --top-p 2 --out "$tmp/x.tfrecord" 2> "$tmp/err"; then exit 1; fi
grep -q "top_p" "$tmp/err"
test ! -e "$tmp/x.tfrecord"
echo "simulate_test: ok"
