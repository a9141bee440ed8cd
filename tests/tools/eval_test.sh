#!/bin/sh
# scenestreamer eval, as a user runs it: small random weights on real WOMD scenarios (a TFRecord, a JSON file with
# metadata and lights, an older one without), each mode and baseline; the JSON keys, determinism across thread
# counts, the plots, and errors that name what was wrong.
# usage: eval_test.sh SCENESTREAMER DATA_DIR
set -eu
bin=$1
data=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
set -- "$data/womd/tfrecord/motion_data_one_scenario.tfrecord" "$data/womd/json/val/womd_27d205cc.json" \
  "$data/womd/json/val/womd_d5b57279.json"

"$bin" init-weights --config small --seed 3 --out "$tmp/w.safetensors" > /dev/null
"$bin" eval --data "$@" --model "$tmp/w.safetensors" --mode motion --rollouts 2 --seed 1 --json "$tmp/motion.json" \
  --plots "$tmp/plots" > "$tmp/motion.txt" 2> "$tmp/progress"
grep -q "realism meta-metric" "$tmp/motion.txt"
for f in linear_speed linear_acceleration angular_speed angular_acceleration distance_to_nearest_object \
  time_to_collision distance_to_road_edge; do
  grep -q "<svg" "$tmp/plots/$f.svg"
done
"$bin" eval --data "$@" --model "$tmp/w.safetensors" --mode full --rollouts 2 --seed 1 --json "$tmp/full.json" > /dev/null 2>&1
"$bin" eval --data "$@" --baseline cv --rollouts 2 --json "$tmp/cv.json" > /dev/null 2>&1
"$bin" eval --data "$@" --baseline log --rollouts 2 --json "$tmp/log.json" > /dev/null 2>&1
/usr/bin/python3 - "$tmp" <<'PY'
import json, math, sys
tmp = sys.argv[1]
keys = ["scenarios", "rollouts", "realism_meta", "kinematic", "interactive", "map", "collision_rate", "offroad_rate",
        "min_ade", "ade_avg", "ade_min", "fde_avg", "fde_min", "add", "fdd", "tracks_to_predict", "evaluated_objects",
        "per_scenario"]
features = ["linear_speed", "linear_acceleration", "angular_speed", "angular_acceleration",
            "distance_to_nearest_object", "collision_indication", "time_to_collision", "distance_to_road_edge",
            "offroad_indication", "traffic_light_violation"]
runs = {name: json.load(open(f"{tmp}/{name}.json")) for name in ["motion", "full", "cv", "log"]}
for name, r in runs.items():
    for k in keys + [f + "_likelihood" for f in features]:
        assert k in r, (name, k)
    assert r["scenarios"] == 3 and r["rollouts"] == 2, (name, r["scenarios"], r["rollouts"])
    assert len(r["per_scenario"]) == 3
    e = r["evaluated_objects"]
    assert e["scenarios_sdc_and_tracks_to_predict"] == 2 and e["scenarios_every_agent_valid_now"] == 1, e
    assert 0 <= r["realism_meta"] <= 1, (name, r["realism_meta"])
    assert ("mmd" in r) == (name == "full"), name
assert set(runs["full"]["mmd"]) == {"strict", "relaxed"}
assert set(runs["full"]["mmd"]["strict"]) == {"position", "heading", "size", "velocity"}
assert runs["motion"]["mode"] == "motion" and runs["cv"]["mode"] is None
assert runs["log"]["realism_meta"] > runs["cv"]["realism_meta"], (runs["log"]["realism_meta"], runs["cv"]["realism_meta"])
assert runs["log"]["min_ade"] == 0 and runs["cv"]["min_ade"] > 0
assert runs["motion"]["add"] > 0  # sampled rollouts differ
assert [s["id"] for s in runs["motion"]["per_scenario"]] == [s["id"] for s in runs["cv"]["per_scenario"]]
PY
# The thread count changes nothing.
"$bin" eval --data "$@" --model "$tmp/w.safetensors" --mode motion --rollouts 2 --seed 1 --threads 1 \
  --json "$tmp/one.json" > /dev/null 2>&1
"$bin" eval --data "$@" --model "$tmp/w.safetensors" --mode motion --rollouts 2 --seed 1 --threads 3 \
  --json "$tmp/three.json" > /dev/null 2>&1
cmp "$tmp/one.json" "$tmp/motion.json"
cmp "$tmp/three.json" "$tmp/motion.json"

# Errors name what was wrong.
if "$bin" eval --data "$1" --model "$tmp/w.safetensors" --mode fast --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "fast" "$tmp/err"
if "$bin" eval --data "$tmp/nope.json" --baseline cv --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "nope.json" "$tmp/err"
if "$bin" eval --data "$1" --model "$tmp/missing.safetensors" --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "missing.safetensors" "$tmp/err"
if "$bin" eval --data "$1" --baseline fancy --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "fancy" "$tmp/err"
if "$bin" eval --data "$1" --baseline cv --rollouts 0 --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "rollouts" "$tmp/err"
if "$bin" eval --data "$1" --baseline cv --json "$tmp/x.json" --bogus 2> "$tmp/err"; then exit 1; fi
grep -q "bogus" "$tmp/err"
if "$bin" eval --data "$1" --baseline cv 2> "$tmp/err"; then exit 1; fi
grep -q "json" "$tmp/err"
test ! -e "$tmp/x.json"
echo "eval_test: ok"
