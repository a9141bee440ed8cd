#!/bin/sh
# WOSAC submissions, as a user makes and scores them: eval writes one (model in motion mode, and constant velocity),
# protoc-generated Python classes of our proto read it as the challenge's validator would, and eval scores the files
# alone to the same numbers it gave directly; simulate's rollouts converted into a submission are scored too; bad
# submissions and flags are refused naming what is wrong. Small: 3 real scenarios, 2 rollouts, small random weights.
# usage: wosac_submission_test.sh SCENESTREAMER DATA_DIR
set -eu
bin=$1
data=$2
here=$(dirname "$0")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
set -- "$data/womd/tfrecord/motion_data_one_scenario.tfrecord" "$data/womd/json/val/womd_27d205cc.json" \
  "$data/womd/json/val/womd_d5b57279.json"

"$bin" init-weights --config small --seed 3 --out "$tmp/w.safetensors" > /dev/null
cat > "$tmp/meta.json" <<'JSON'
{"account_name": "someone@example.org", "unique_method_name": "scenestreamer-test", "authors": ["A. Author"],
 "affiliation": "nowhere", "num_model_parameters": "1M", "uses_lidar_data": false, "uses_camera_data": false,
 "uses_public_model_pretraining": false}
JSON
"$bin" eval --data "$@" --model "$tmp/w.safetensors" --rollouts 2 --seed 1 --wosac-submission "$tmp/sub" \
  --submission-metadata "$tmp/meta.json" --json "$tmp/direct.json" > "$tmp/direct.txt" 2> /dev/null
grep -q "submission: 3 scenarios x 2 rollouts in 1 shard(s)" "$tmp/direct.txt"
grep -q "not yet valid for the challenge: 3 scenario(s) do not have 32 rollouts" "$tmp/direct.txt"
grep -q "acknowledge_complies_with_closed_loop_requirement" "$tmp/direct.txt"
test -s "$tmp/sub/submission.binproto-00000-of-00001"
"$bin" eval --data "$@" --submission "$tmp/sub" --json "$tmp/files.json" > /dev/null 2>&1
"$bin" eval --data "$@" --baseline cv --rollouts 2 --wosac-submission "$tmp/sub_cv" --json "$tmp/cv_direct.json" \
  > /dev/null 2>&1
"$bin" eval --data "$@" --submission "$tmp/sub_cv/submission.binproto-00000-of-00001" --json "$tmp/cv_files.json" \
  > /dev/null 2>&1
"$bin" convert "$@" --out "$tmp/logs.tfrecord" > /dev/null

/usr/bin/python3 - "$tmp" "$here" <<'PY'
import json, sys
tmp, here = sys.argv[1:3]
sys.path.insert(0, here)
import womd_files
scenario_pb2, submission_pb2 = womd_files.classes()
logs = {s.scenario_id: s for s in womd_files.scenarios(f"{tmp}/logs.tfrecord", scenario_pb2)}

# What the challenge's validator checks (submission_specs.py): every object valid at the current frame, exactly
# once, 80 steps of x, y, z, heading; the scenario id; the metadata.
sub = submission_pb2.SimAgentsChallengeSubmission()
sub.ParseFromString(open(f"{tmp}/sub/submission.binproto-00000-of-00001", "rb").read())
assert sub.submission_type == submission_pb2.SimAgentsChallengeSubmission.SIM_AGENTS_SUBMISSION
assert sub.account_name == "someone@example.org" and list(sub.authors) == ["A. Author"]
assert sub.num_model_parameters == "1M" and not sub.acknowledge_complies_with_closed_loop_requirement
assert sorted(r.scenario_id for r in sub.scenario_rollouts) == sorted(logs)
for r in sub.scenario_rollouts:
    log = logs[r.scenario_id]
    now = log.current_time_index
    sim_agents = [t.id for t in log.tracks if t.states[now].valid]
    assert len(r.joint_scenes) == 2
    for j in r.joint_scenes:
        assert [t.object_id for t in j.simulated_trajectories] == sim_agents
        for t in j.simulated_trajectories:
            assert len(t.center_x) == len(t.center_y) == len(t.center_z) == len(t.heading) == 80
    # z: the model works in the plane; each agent keeps its current logged z.
    for t in r.joint_scenes[0].simulated_trajectories:
        z = next(tr for tr in log.tracks if tr.id == t.object_id).states[now].center_z
        assert all(abs(v - z) < 1e-3 for v in t.center_z), (t.object_id, t.center_z[0], z)
    assert r.joint_scenes[0] != r.joint_scenes[1]  # sampled rollouts differ

# Scored from the files alone: the same numbers as eval gave directly.
def metrics(path):
    r = json.load(open(path))
    drop = {"policy", "mode", "seed", "model", "model_coverage", "model_driven_share", "sampling"}
    def clean(x):
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items() if k not in drop}
        if isinstance(x, list):
            return [clean(v) for v in x]
        return x
    return clean(r)
for a, b in [("direct", "files"), ("cv_direct", "cv_files")]:
    da, db = metrics(f"{tmp}/{a}.json"), metrics(f"{tmp}/{b}.json")
    assert da == db, [(k, da[k], db.get(k)) for k in da if da[k] != db.get(k)][:3]
    assert json.load(open(f"{tmp}/{b}.json"))["policy"] == "submission"
    assert 0 < da["realism_meta"] < 1 and da["scenarios"] == 3 and da["rollouts"] == 2
assert metrics(f"{tmp}/direct.json")["realism_meta"] != metrics(f"{tmp}/cv_direct.json")["realism_meta"]

# A submission another tool would make: the challenge's regex also takes an unnumbered NAME.binproto. Here, one
# object removed from a joint scene, and an object that is not a sim agent.
for name, edit in [("missing", lambda s: s.scenario_rollouts[0].joint_scenes[1].simulated_trajectories.pop(0)),
                   ("stranger", lambda s: setattr(s.scenario_rollouts[0].joint_scenes[0].simulated_trajectories[0],
                                                  "object_id", 987654))]:
    bad = submission_pb2.SimAgentsChallengeSubmission()
    bad.CopyFrom(sub)
    edit(bad)
    import os
    os.makedirs(f"{tmp}/{name}")
    open(f"{tmp}/{name}/mine.binproto", "wb").write(bad.SerializeToString())
PY
if "$bin" eval --data "$@" --submission "$tmp/missing" --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "rollout 1: sim agent .* (valid at the current frame) is missing" "$tmp/err"
if "$bin" eval --data "$@" --submission "$tmp/stranger" --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "rollout 0: object 987654 is not in the scenario" "$tmp/err"

# simulate's rollouts (complete WOMD scenarios), converted into a submission, scored by eval. simulate --seed S
# --rollout K makes eval's K-th rollout (one definition of the closed-loop rollout, the SDC included): converted, the
# two equal the trajectories of eval's own submission of that scenario (to float32 rounding).
for k in 0 1; do
  "$bin" simulate --scenario "$1" --model "$tmp/w.safetensors" --seed 1 --rollout $k --out "$tmp/r$k.tfrecord" > /dev/null
done
"$bin" convert "$tmp/r0.tfrecord" "$tmp/r1.tfrecord" --wosac-submission "$tmp/conv" > "$tmp/conv.txt"
grep -q "wrote 2 rollouts of 1 scenarios" "$tmp/conv.txt"
"$bin" eval --data "$1" --submission "$tmp/conv" --json "$tmp/conv.json" > /dev/null 2>&1
/usr/bin/python3 - "$tmp" "$here" <<'PY'
import json, math, sys
tmp, here = sys.argv[1:3]
sys.path.insert(0, here)
import womd_files
_, submission_pb2 = womd_files.classes()
def read(path):
    s = submission_pb2.SimAgentsChallengeSubmission()
    s.ParseFromString(open(path, "rb").read())
    return s
(conv,) = read(f"{tmp}/conv/submission.binproto-00000-of-00001").scenario_rollouts
(ours,) = [r for r in read(f"{tmp}/sub/submission.binproto-00000-of-00001").scenario_rollouts
           if r.scenario_id == conv.scenario_id]
assert len(conv.joint_scenes) == len(ours.joint_scenes) == 2
for a, b in zip(conv.joint_scenes, ours.joint_scenes):
    assert [t.object_id for t in a.simulated_trajectories] == [t.object_id for t in b.simulated_trajectories]
    for ta, tb in zip(a.simulated_trajectories, b.simulated_trajectories):
        for f in range(80):
            assert abs(ta.center_x[f] - tb.center_x[f]) < 2e-3 and abs(ta.center_y[f] - tb.center_y[f]) < 2e-3, \
                (ta.object_id, f, ta.center_x[f], tb.center_x[f], ta.center_y[f], tb.center_y[f])
            assert ta.center_z[f] == tb.center_z[f]
            d = ta.heading[f] - tb.heading[f]
            assert abs(math.atan2(math.sin(d), math.cos(d))) < 1e-4, (ta.object_id, f, ta.heading[f], tb.heading[f])
r = json.load(open(f"{tmp}/conv.json"))
assert r["scenarios"] == 1 and r["rollouts"] == 2 and 0 < r["realism_meta"] < 1, r["realism_meta"]
assert r["add"] > 0  # two different rollouts
PY

# The challenge's test set holds history only (scenarios end at their current frame): eval rolls them out for 80
# frames and writes them, with nothing to score. Made here by cutting the real TFRecord scenario after frame 10.
/usr/bin/python3 - "$tmp" "$here" "$1" <<'PY'
import sys
tmp, here, log_path = sys.argv[1:4]
sys.path.insert(0, here)
import womd_files
scenario_pb2, _ = womd_files.classes()
(s,) = womd_files.scenarios(log_path, scenario_pb2)
keep = s.current_time_index + 1
del s.timestamps_seconds[keep:]
del s.dynamic_map_states[keep:]
for t in s.tracks:
    del t.states[keep:]
womd_files.write_tfrecord(f"{tmp}/history.tfrecord", [s.SerializeToString()])
PY
if "$bin" eval --data "$tmp/history.tfrecord" --model "$tmp/w.safetensors" --rollouts 2 --json "$tmp/x.json" \
  2> "$tmp/err"; then exit 1; fi
grep -q "no frame after the current frame" "$tmp/err"  # nothing to score without --wosac-submission
"$bin" eval --data "$tmp/history.tfrecord" --model "$tmp/w.safetensors" --rollouts 2 --wosac-submission "$tmp/sub_test" \
  --json "$tmp/test.json" > "$tmp/test.txt" 2> /dev/null
grep -q "1 scenario(s) end at their current frame (the challenge's test set): rolled out for 80 frames" "$tmp/test.txt"
/usr/bin/python3 - "$tmp" "$here" <<'PY'
import json, sys
tmp, here = sys.argv[1:3]
sys.path.insert(0, here)
import womd_files
scenario_pb2, submission_pb2 = womd_files.classes()
(log,) = womd_files.scenarios(f"{tmp}/history.tfrecord", scenario_pb2)
sub = submission_pb2.SimAgentsChallengeSubmission()
sub.ParseFromString(open(f"{tmp}/sub_test/submission.binproto-00000-of-00001", "rb").read())
(r,) = sub.scenario_rollouts
assert r.scenario_id == log.scenario_id and len(r.joint_scenes) == 2
for j in r.joint_scenes:
    assert [t.object_id for t in j.simulated_trajectories] == [t.id for t in log.tracks if t.states[10].valid]
    assert all(len(t.center_x) == 80 and len(t.heading) == 80 for t in j.simulated_trajectories)
assert json.load(open(f"{tmp}/test.json"))["realism_meta"] is None  # no logged future: undefined
PY

# Errors name what was wrong.
if "$bin" eval --data "$1" "$2" --submission "$tmp/sub" --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "scenario(s) that --data does not" "$tmp/err"
if "$bin" eval --data "$@" "$data/womd/json/val/womd_0fd19aa8.json" --submission "$tmp/sub" --json "$tmp/x.json" \
  2> "$tmp/err"; then exit 1; fi
grep -q "has no rollouts of scenario" "$tmp/err"
if "$bin" eval --data "$@" --submission "$tmp/sub" --rollouts 3 --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q -- "--rollouts does not apply" "$tmp/err"
if "$bin" eval --data "$@" --submission "$tmp/sub" --sdc log --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q -- "--sdc model only" "$tmp/err"
if "$bin" eval --data "$1" --model "$tmp/w.safetensors" --mode full --wosac-submission "$tmp/y" --json "$tmp/x.json" \
  2> "$tmp/err"; then exit 1; fi
grep -q "motion mode" "$tmp/err"
if "$bin" eval --data "$1" --baseline log --wosac-submission "$tmp/y" --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "log replay" "$tmp/err"
if "$bin" eval --data "$1" --baseline cv --sdc log --wosac-submission "$tmp/y" --json "$tmp/x.json" 2> "$tmp/err"; then
  exit 1
fi
grep -q "SDC" "$tmp/err"
echo '{"acount_name": "x"}' > "$tmp/badmeta.json"
if "$bin" eval --data "$1" --baseline cv --wosac-submission "$tmp/y" --submission-metadata "$tmp/badmeta.json" \
  --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q 'unknown key "acount_name"' "$tmp/err"
printf 'not a proto at all' > "$tmp/junk.binproto"
if "$bin" eval --data "$1" --submission "$tmp/junk.binproto" --json "$tmp/x.json" 2> "$tmp/err"; then exit 1; fi
grep -q "junk.binproto: not a SimAgentsChallengeSubmission" "$tmp/err"
if "$bin" convert "$1" --out "$tmp/x.tfrecord" --wosac-submission "$tmp/y" 2> "$tmp/err"; then exit 1; fi
grep -q "not both" "$tmp/err"
test ! -e "$tmp/x.json" && test ! -e "$tmp/y"
echo "wosac_submission_test: ok"
