#!/bin/sh
# scenestreamer eval, as a user runs it: small random weights on real WOMD scenarios (a TFRecord, a JSON file with
# metadata and lights, an older one without, a 20 s one), each mode and baseline, both --sdc rules; the JSON keys,
# per-scenario results and windows, determinism across thread counts, the plots, --compare on hand-made results, and
# errors that name what was wrong.
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
# Full mode: the agents placed at the first step against the log's, overall and per scenario.
p = runs["full"]["placed_agents"]
assert p["log"]["agents"] > 0 and p["generated_per_rollout"]["agents"] >= 0, p
assert p["log"]["vehicles"] <= p["log"]["agents"] and 0 <= p["scenarios_count_within_30pct"] <= p["scenarios_with_log_agents"] <= 3, p
# The correlation of the counts over scenarios: null below 3 scenarios or without spread, else in [-1, 1].
assert p["count_correlation"] is None or -1 <= p["count_correlation"] <= 1, p
assert all("placed_agents" in s for s in runs["full"]["per_scenario"])
assert all("placed_agents" not in r for name, r in runs.items() if name != "full")
assert runs["motion"]["sampling"] == {"top_p": 0.8, "temperature": 0.7, "motion_reject": True} and "sampling" not in runs["cv"]
assert runs["motion"]["mode"] == "motion" and runs["cv"]["mode"] is None
assert runs["log"]["realism_meta"] > runs["cv"]["realism_meta"], (runs["log"]["realism_meta"], runs["cv"]["realism_meta"])
assert runs["log"]["min_ade"] == 0 and runs["cv"]["min_ade"] > 0
assert runs["motion"]["add"] > 0  # sampled rollouts differ
assert [s["id"] for s in runs["motion"]["per_scenario"]] == [s["id"] for s in runs["cv"]["per_scenario"]]
# --sdc model is the default: the SDC is evaluated wherever the scenario names one.
for name, r in runs.items():
    assert r["sdc"] == "model", (name, r["sdc"])
    assert len(r["windows"]) == 1 and r["windows"][0]["window"] == "0-8 s", r["windows"]  # 91 frames: one window
    assert r["windows"][0]["realism_meta"] == r["realism_meta"]
    for s in r["per_scenario"]:
        for k in ["realism_meta", "kinematic", "interactive", "map", "collision_rate", "offroad_rate", "min_ade",
                  "evaluated_ids", "sdc_id", "sdc_evaluated", "windows", "future_frames", "tracks_to_predict"]:
            assert k in s, (name, k)
        assert s["future_frames"] == 80 and len(s["windows"]) == 1
        assert s["sdc_evaluated"] == (s["sdc_id"] is not None), s
    assert ("model_driven_share" in r["per_scenario"][0]) == (name in ("motion", "full")), name
m = runs["motion"]["per_scenario"]
assert all(0 < s["model_driven_share"] <= 1 for s in m), [s["model_driven_share"] for s in m]
PY

# --sdc log: the SDC follows its log and is not among the evaluated objects (the TFRecord names it and 3 tracks to
# predict; the older JSON file names no SDC, so nothing changes there).
"$bin" eval --data "$@" --model "$tmp/w.safetensors" --sdc log --rollouts 2 --seed 1 --json "$tmp/motion_log.json" \
  > "$tmp/motion_log.txt" 2> /dev/null
grep -q "SDC: --sdc log" "$tmp/motion_log.txt"
"$bin" eval --data "$@" --baseline cv --sdc log --rollouts 2 --json "$tmp/cv_log.json" > /dev/null 2>&1
/usr/bin/python3 - "$tmp" <<'PY'
import json, sys
tmp = sys.argv[1]
for name in ["motion", "cv"]:
    model_rule = json.load(open(f"{tmp}/{name}.json"))
    log_rule = json.load(open(f"{tmp}/{name}_log.json"))
    assert log_rule["sdc"] == "log"
    for m, l in zip(model_rule["per_scenario"], log_rule["per_scenario"]):
        assert m["id"] == l["id"]
        assert l["sdc_evaluated"] is False and l["sdc_id"] not in l["evaluated_ids"], l
        if m["sdc_id"] is not None:
            assert m["evaluated_ids"] == sorted(l["evaluated_ids"] + [m["sdc_id"]]), (m["evaluated_ids"], l["evaluated_ids"])
        else:
            assert m["evaluated_ids"] == l["evaluated_ids"]
    assert log_rule["evaluated_objects"]["objects"] == model_rule["evaluated_objects"]["objects"] - 2  # two SDCs
PY

# A 20 s scenario is rolled out to its end and scored per window; the readers take its 198 frames.
long="$data/womd/json-20s/womd20s_92ddde4b.json"
"$bin" eval --data "$long" --baseline cv --rollouts 2 --json "$tmp/long_cv.json" > "$tmp/long_cv.txt" 2> /dev/null
grep -q "16 s-end" "$tmp/long_cv.txt"
"$bin" eval --data "$long" --model "$tmp/w.safetensors" --rollouts 1 --seed 1 --json "$tmp/long_model.json" > /dev/null 2>&1
/usr/bin/python3 - "$tmp" <<'PY'
import json, sys
tmp = sys.argv[1]
for name in ["long_cv", "long_model"]:
    r = json.load(open(f"{tmp}/{name}.json"))
    s = r["per_scenario"][0]
    assert s["future_frames"] == 187, s["future_frames"]
    assert [w["window"] for w in s["windows"]] == ["0-8 s", "8-16 s", "16 s-end"], s["windows"]
    assert [(w["from_s"], w["to_s"]) for w in r["windows"]] == [(0, 8), (8, 16), (16, None)], r["windows"]
    assert all(w["scenarios"] == 1 for w in r["windows"])
    assert s["sdc_evaluated"] and s["evaluated_objects"] == s["sim_agents"]  # no tracks to predict: every agent
    for w in s["windows"]:
        assert 0 < w["realism_meta"] <= 1 and w["min_ade"] > 0, w
cv = json.load(open(f"{tmp}/long_cv.json"))["per_scenario"][0]["windows"]
assert cv[0]["min_ade"] < cv[1]["min_ade"] < cv[2]["min_ade"], cv  # constant velocity drifts
PY

# --compare on hand-made results with known differences: realism B = A + 0.05 everywhere (interval [0.05, 0.05]);
# minADE differs by 0 in two scenarios and 2 in the other two (difference 1, interval [0, 2]); one scenario's
# likelihood is undefined in B (it does not pair).
/usr/bin/python3 - "$tmp" <<'PY'
import json, sys
tmp = sys.argv[1]
features = ["linear_speed", "linear_acceleration", "angular_speed", "angular_acceleration",
            "distance_to_nearest_object", "collision_indication", "time_to_collision", "distance_to_road_edge",
            "offroad_indication", "traffic_light_violation"]
def result(shift, ade_extra, undefined):
    per = []
    for i in range(4):
        s = {"id": f"s{i}", "realism_meta": 0.5 + 0.1 * i + shift, "collision_rate": 0.1, "offroad_rate": 0.2,
             "min_ade": 1.0 + (ade_extra if i >= 2 else 0), "evaluated_ids": [1, 2]}
        for f in features:
            s[f + "_likelihood"] = 0.5 + shift
        if undefined and i == 0:
            s["linear_speed_likelihood"] = None
        per.append(s)
    return {"sdc": "model", "policy": "hand-made", "rollouts": 1, "per_scenario": per}
json.dump(result(0, 0, False), open(f"{tmp}/A.json", "w"))
json.dump(result(0.05, 2, True), open(f"{tmp}/B.json", "w"))
r = result(0, 0, False); r["sdc"] = "log"; json.dump(r, open(f"{tmp}/A_log.json", "w"))
r = result(0, 0, False); r["per_scenario"] = r["per_scenario"][:3]; json.dump(r, open(f"{tmp}/A_three.json", "w"))
PY
"$bin" eval --compare "$tmp/A.json" "$tmp/B.json" --json "$tmp/diff.json" > "$tmp/diff.txt"
grep -q "realism_meta" "$tmp/diff.txt"
/usr/bin/python3 - "$tmp/diff.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
m = {x["name"]: x for x in d["metrics"]}
assert d["scenarios"] == 4 and d["resamples"] == 10000 and d["level"] == 0.95, d
def near(a, b): return abs(a - b) < 1e-9
r = m["realism_meta"]
assert near(r["difference"], 0.05) and near(r["low"], 0.05) and near(r["high"], 0.05) and r["excludes_zero"], r
a = m["min_ade"]
assert near(a["a"], 1.0) and near(a["b"], 2.0) and near(a["low"], 0.0) and near(a["high"], 2.0), a
assert not a["excludes_zero"]
assert m["linear_speed_likelihood"]["scenarios"] == 3 and m["angular_speed_likelihood"]["scenarios"] == 4
assert near(m["kinematic"]["difference"], 0.05) and m["kinematic"]["scenarios"] == 3
assert m["collision_rate"]["difference"] == 0 and m["ade_avg"]["a"] is None  # absent: undefined
PY
# Compare errors name what does not pair.
if "$bin" eval --compare "$tmp/A.json" "$tmp/A_log.json" 2> "$tmp/err"; then exit 1; fi
grep -q "sdc" "$tmp/err"
if "$bin" eval --compare "$tmp/A.json" "$tmp/A_three.json" 2> "$tmp/err"; then exit 1; fi
grep -q "s3" "$tmp/err"
if "$bin" eval --compare "$tmp/A.json" "$tmp/nope.json" 2> "$tmp/err"; then exit 1; fi
grep -q "nope.json" "$tmp/err"
if "$bin" eval --compare "$tmp/A.json" 2> "$tmp/err"; then exit 1; fi
grep -q "two result files" "$tmp/err"
if "$bin" eval --compare "$tmp/A.json" "$tmp/B.json" --bootstrap 5 2> "$tmp/err"; then exit 1; fi
grep -q "bootstrap" "$tmp/err"
if "$bin" eval --compare "$tmp/A.json" "$tmp/progress" 2> "$tmp/err"; then exit 1; fi
grep -q "invalid JSON" "$tmp/err"
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
# Without --model: the bundled default model, for a program in its build tree the source tree's, never one in the
# working directory (tests/integration/install_test.py covers an installed program and one without its share/).
src=$(cd "$(dirname "$0")/../.." && pwd -P)
mkdir -p "$tmp/cwd/models" && cp "$tmp/w.safetensors" "$tmp/cwd/models/default.safetensors"
(cd "$tmp/cwd" && "$bin" eval --data "$1" --rollouts 1 --json x.json > /dev/null 2>&1)
grep -q "\"model\": *\"$src/models/default.safetensors\"" "$tmp/cwd/x.json"
if "$bin" eval --data "$1" --baseline cv --sdc ego --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "ego" "$tmp/err"
if "$bin" eval --data "$1" --baseline fancy --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "fancy" "$tmp/err"
# Sampling flags: the model's only, in range; reported in the JSON.
"$bin" eval --data "$1" --model "$tmp/w.safetensors" --rollouts 1 --top-p 0.5 --temperature 0.7 --json "$tmp/t.json" > /dev/null 2>&1
grep -q '"top_p": 0.5' "$tmp/t.json" && grep -q '"temperature": 0.7' "$tmp/t.json"
if "$bin" eval --data "$1" --model "$tmp/w.safetensors" --top-p 1.5 --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "top-p" "$tmp/err"
if "$bin" eval --data "$1" --model "$tmp/w.safetensors" --temperature 0 --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "temperature" "$tmp/err"
if "$bin" eval --data "$1" --baseline cv --temperature 0.5 --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "temperature" "$tmp/err"
if "$bin" eval --data "$1" --baseline cv --rollouts 0 --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "rollouts" "$tmp/err"
if "$bin" eval --data "$1" --baseline cv --json "$tmp/x.json" --bogus 2> "$tmp/err"; then exit 1; fi
grep -q "bogus" "$tmp/err"
if "$bin" eval --data "$1" --baseline cv 2> "$tmp/err"; then exit 1; fi
grep -q "json" "$tmp/err"
test ! -e "$tmp/x.json"
echo "eval_test: ok"
