#!/bin/sh
# scenestreamer simulate, as a user runs it: random small weights, a real scenario, each mode, both --sdc rules, a
# 20 s scenario to its end; the rollout is a complete WOMD scenario (the log up to its current frame, the rollout
# after it) that inspect, render, convert and protoc-generated Python classes read back.
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
assert r["frames"] == 91, r["frames"]             # the log's 11 frames, then 16 steps at 10 Hz
assert r["scenario_id"] == "637f20cafde22ff8", r["scenario_id"]
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
assert free["frames"] == 91 and free["sdc_track_index"] >= 0, (free["frames"], free["sdc_track_index"])
long = json.load(open(sys.argv[1] + "/long.json"))
assert long["frames"] == 201 and long["sdc_track_index"] >= 0, (long["frames"], long["sdc_track_index"])  # 11 + 38 * 5
PY

# Round trip, read by another tool: protoc-generated Python classes of proto/womd and our own TFRecord framing
# reader see, up to the current frame, the log's frames, ids, current index and history; z after it is each
# track's last logged z; agents the model created (densify) are new tracks with ids the log does not use.
/usr/bin/python3 - "$tmp" "$scenario" "$(dirname "$0")" <<'PY'
import math, sys
tmp, log_path, here = sys.argv[1:4]
sys.path.insert(0, here)
import womd_files
scenario_pb2, _ = womd_files.classes()
(log,) = womd_files.scenarios(log_path, scenario_pb2)
now = log.current_time_index
assert now == 10
for name in ["motion", "densify", "free"]:
    (r,) = womd_files.scenarios(f"{tmp}/{name}.tfrecord", scenario_pb2)
    assert r.scenario_id == log.scenario_id and r.current_time_index == now, (r.scenario_id, r.current_time_index)
    assert r.sdc_track_index == log.sdc_track_index
    assert list(r.tracks_to_predict) == list(log.tracks_to_predict)
    assert list(r.objects_of_interest) == list(log.objects_of_interest)
    assert len(r.map_features) == len(log.map_features)
    assert len(r.timestamps_seconds) == 91
    assert list(r.timestamps_seconds[:now + 1]) == list(log.timestamps_seconds[:now + 1])
    for f in range(now + 1, 91):
        assert abs(r.timestamps_seconds[f] - r.timestamps_seconds[f - 1] - 0.1) < 1e-9
    log_ids = [t.id for t in log.tracks]
    assert [t.id for t in r.tracks[:len(log.tracks)]] == log_ids
    for t, lt in zip(r.tracks, log.tracks):
        assert t.object_type == lt.object_type and len(t.states) == 91
        for f in range(now + 1):
            assert t.states[f] == lt.states[f], (name, t.id, f)
        z = [s.center_z for s in lt.states[:now + 1] if s.valid]
        for s in t.states[now + 1:]:
            if s.valid:
                assert s.center_z == z[-1], (name, t.id, s.center_z, z[-1])
                assert s.center_z != 0
    new = r.tracks[len(log.tracks):]
    assert not set(t.id for t in new) & set(log_ids)
    assert len(set(t.id for t in r.tracks)) == len(r.tracks)
    for t in new:
        assert not any(s.valid for s in t.states[:now + 1])
        assert any(s.valid for s in t.states[now + 1:])
    if name == "densify":
        assert new, "densify created no agent"
    sdc = r.tracks[r.sdc_track_index]
    assert all(s.valid for s in sdc.states[now:]), name  # the SDC is driven over the whole rollout
    assert len(r.dynamic_map_states) == 91
    for f in range(now + 1):
        assert r.dynamic_map_states[f] == log.dynamic_map_states[f]
    assert all(len(d.lane_states) > 0 for d in r.dynamic_map_states[now + 1:])  # the model's lights
PY
# The project's reader reads it back whole: converting it again gives the same bytes.
"$bin" convert "$tmp/motion.tfrecord" --out "$tmp/motion_again.tfrecord" > /dev/null
cmp "$tmp/motion.tfrecord" "$tmp/motion_again.tfrecord"
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
if "$bin" simulate --scenario "$scenario" --model "$tmp/w.safetensors" --kv-precision bf16 --out "$tmp/x.tfrecord" 2> "$tmp/err"; then exit 1; fi
grep -q "unknown KV precision 'bf16'" "$tmp/err"
test ! -e "$tmp/x.tfrecord"
# The precisions are the engine's options, as the server's flags set them: fp32 keys and products give other bits.
"$bin" simulate --scenario "$scenario" --model "$tmp/w.safetensors" --steps 8 --seed 1 --out "$tmp/p16.tfrecord" > /dev/null
"$bin" simulate --scenario "$scenario" --model "$tmp/w.safetensors" --steps 8 --seed 1 --kv-precision fp32 \
  --matmul-precision fp32 --out "$tmp/p32.tfrecord" > /dev/null
if cmp -s "$tmp/p16.tfrecord" "$tmp/p32.tfrecord"; then echo "--kv-precision fp32 changed nothing" >&2; exit 1; fi
echo "simulate_test: ok"
