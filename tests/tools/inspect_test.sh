#!/bin/sh
# scenestreamer inspect and convert, run as a user would, on the real WOMD files (read in place from ../shared).
# usage: inspect_test.sh SCENESTREAMER DATA_DIR
set -eu
bin=$1
data=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# The JSON report of the native TFRecord has the documented keys and the README's counts.
"$bin" inspect --json "$data/womd/tfrecord/motion_data_one_scenario.tfrecord" > "$tmp/one.json"
/usr/bin/python3 - "$tmp/one.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
for key in ["scenario_id", "tracks", "map_features", "segments", "motion_ace_mean", "motion_ace_max",
            "motion_ace_by_type", "state_roundtrip_max_error"]:
    assert key in r, key
assert r["scenario_id"] == "637f20cafde22ff8", r["scenario_id"]
assert r["tracks"] == {"vehicle": 70, "pedestrian": 10, "cyclist": 3, "total": 83}, r["tracks"]
assert r["map_features"]["total"] == 301, r["map_features"]
assert r["map_features"]["lane"] == 199 and r["map_features"]["crosswalk"] == 4, r["map_features"]
assert r["segments"]["kept"] > 301, r["segments"]
assert 0 < r["motion_ace_mean"] < 0.1, r["motion_ace_mean"]
assert set(r["state_roundtrip_max_error"]) == {"length", "width", "height", "u", "v", "heading", "vx", "vy"}
PY

# convert: JSON -> TFRecord keeps everything inspect reports.
json="$data/womd/json/val/womd_27d205cc.json"
"$bin" convert "$json" --out "$tmp/c.tfrecord"
"$bin" inspect --json "$json" > "$tmp/a.json"
"$bin" inspect --json "$tmp/c.tfrecord" > "$tmp/b.json"
cmp "$tmp/a.json" "$tmp/b.json"

# Several inputs: one object with per-scenario reports and a summary.
"$bin" inspect --json "$data/womd/tfrecord" > "$tmp/many.json"
/usr/bin/python3 -c "
import json, sys
r = json.load(open('$tmp/many.json'))
assert len(r['scenarios']) == 2 and r['summary']['scenarios'] == 2, r.keys()
"

# Errors: a missing file, a bad flag, a corrupt file; each a clear message and a non-zero exit.
if "$bin" inspect "$tmp/nope.tfrecord" 2> "$tmp/err"; then exit 1; fi
grep -q "nope.tfrecord" "$tmp/err"
if "$bin" inspect --bogus "$json" 2> "$tmp/err"; then exit 1; fi
grep -q "unknown flag --bogus" "$tmp/err"
head -c 100 "$tmp/c.tfrecord" > "$tmp/cut.tfrecord"
if "$bin" convert "$tmp/cut.tfrecord" --out "$tmp/x.tfrecord" 2> "$tmp/err"; then exit 1; fi
grep -q "cut.tfrecord" "$tmp/err"
test ! -e "$tmp/x.tfrecord"
echo "inspect_test: ok"
