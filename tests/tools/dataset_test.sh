#!/bin/sh
# scenestreamer dataset sumo and stats, run as a user would: a small dataset generated twice with different worker
# counts is the same bytes, reads back, and has a consistent MANIFEST; stats on it and on the real scenarios; and the
# error paths (SUMO missing, a network step failing, bad arguments).
# usage: dataset_test.sh SCENESTREAMER DATA_DIR
set -eu
bin=$1
data=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

if ! command -v sumo >/dev/null 2>&1; then
  echo "sumo is not installed (Debian packages sumo, sumo-tools): nothing to test"
  exit 0
fi

# Short runs: 60 s warm-up, 20 s recorded (3 windows per job), so the whole test takes seconds.
small="--scenarios 30 --seed 5 --warmup 60 --record 20 --shard-size 12 --quiet --tmp $tmp"
"$bin" dataset sumo --out "$tmp/a" $small --workers 2 > "$tmp/a.log"
"$bin" dataset sumo --out "$tmp/b" $small --workers 1 > "$tmp/b.log"
grep -q "wrote 30 scenarios in 3 shards" "$tmp/a.log"
# Determinism: the same files, byte for byte, whatever the number of workers.
test "$(cd "$tmp/a" && ls)" = "$(cd "$tmp/b" && ls)"
for f in "$tmp"/a/*; do cmp "$f" "$tmp/b/$(basename "$f")"; done
# Job directories are cleaned up.
test -z "$(ls -d "$tmp"/scenestreamer-sumo-* 2>/dev/null)"

/usr/bin/python3 - "$tmp/a" <<'PY'
import json, os, sys
d = sys.argv[1]
m = json.load(open(os.path.join(d, "MANIFEST")))
assert m["scenarios"] == 30 and m["frames"] == 91 and m["current_time_index"] == 10, m
assert [s["scenarios"] for s in m["shards"]] == [12, 12, 6], m["shards"]
assert sorted(os.listdir(d)) == sorted(["MANIFEST"] + [s["file"] for s in m["shards"]])
assert sum(m["scenarios_by_network"].values()) == 30, m["scenarios_by_network"]
assert sum(j["scenarios_used"] for j in m["jobs"]) == 30
assert m["tracks_by_type"].get("vehicle", 0) >= 30, m["tracks_by_type"]  # at least the egos
assert m["validation"]["scenarios_read_back_and_tokenized"] == 30, m["validation"]
assert 0 < m["validation"]["motion_ace_mean_m"] < 0.2, m["validation"]
assert [j["network"] for j in m["jobs"][:3]] == ["grid", "spider", "rand"]
PY

# The engine's reader takes the directory (the MANIFEST is not a scenario file); stats reads it beside real data
# (every real file: 11 s of CPU for the 227 there were when this was written, of the test's ~80 s).
"$bin" inspect --json "$tmp/a" > "$tmp/inspect.json"
"$bin" dataset stats --json "$tmp/a" "$data/womd/json" > "$tmp/stats.json"
/usr/bin/python3 - "$tmp/inspect.json" "$tmp/stats.json" "$tmp/a" "$data/womd/json" "$data/womd/README.md" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
assert r["summary"]["scenarios"] == 30
s = json.load(open(sys.argv[2]))
gen, real = s[sys.argv[3]], s[sys.argv[4]]
# The real scenarios are the files the data's README lists in its table (one row per file).
readme = open(sys.argv[5]).read().splitlines()
listed = [l for l in readme if l.startswith("| json/")]
with_lights = [l for l in listed if l.split("|")[4].strip() == "yes"]
assert len(listed) >= 200, len(listed)
assert gen["scenarios"] == 30 and real["scenarios"] == len(listed), (gen["scenarios"], real["scenarios"], len(listed))
assert real["lights_per_scenario"]["with_lights"] == len(with_lights), (real["lights_per_scenario"], len(with_lights))
roads = sum(int(l.split("|")[3]) for l in listed)
assert abs(sum(real["map_features_per_scenario"].values()) * len(listed) - roads) < 0.5, (real, roads)
for k in ["agents_per_scenario", "lights_per_scenario", "speed_mps", "frames", "map_features_per_scenario"]:
    assert k in gen and k in real, k
assert gen["frames"] == {"min": 91, "max": 91}
assert gen["agents_per_scenario"]["vehicle"]["mean"] >= 1
assert 0 < gen["speed_mps"]["vehicle"]["mean"] < 40
PY
"$bin" dataset stats "$tmp/a" | grep -q "vehicle speed m/s"

# The bundled sample (data/) is what data/README.md's command makes, byte for byte (with the SUMO it was made with).
repo=$(cd "$(dirname "$0")/../.." && pwd)
if [ -f "$repo/data/MANIFEST" ] && grep -q "\"sumo_version\": \"$(sumo --version | head -1)\"" "$repo/data/MANIFEST"; then
  "$bin" dataset sumo --out "$tmp/sample" --scenarios 20 --seed 1 --record 10 --radius 60 --map-radius 80 \
    --quiet --tmp "$tmp" > /dev/null
  cmp "$tmp/sample/MANIFEST" "$repo/data/MANIFEST"
  cmp "$tmp/sample/sumo.tfrecord-00000-of-00001" "$repo/data/sumo.tfrecord-00000-of-00001"
fi

# Errors: each a clear message naming the step, and a non-zero exit.
# SUMO missing from PATH.
if PATH=/nonexistent "$bin" dataset sumo --out "$tmp/c" $small 2> "$tmp/err"; then exit 1; fi
grep -q "step check: SUMO is missing: sumo not found in PATH" "$tmp/err"
# --sumo-bin naming a directory without SUMO.
if "$bin" dataset sumo --out "$tmp/c" $small --sumo-bin "$tmp/nowhere" 2> "$tmp/err"; then exit 1; fi
grep -q "SUMO is missing: $tmp/nowhere/sumo: no such executable file" "$tmp/err"
# A network step that fails: netgenerate exits with an error (on every retry); the message names the job, seed,
# network and step.
mkdir "$tmp/bin"
ln -s "$(command -v sumo)" "$tmp/bin/sumo"
ln -s "$(command -v netconvert)" "$tmp/bin/netconvert"
printf '#!/bin/sh\necho "Error: no memory for the grid" >&2\nexit 3\n' > "$tmp/bin/netgenerate"
chmod +x "$tmp/bin/netgenerate"
if "$bin" dataset sumo --out "$tmp/c" $small --networks grid --sumo-bin "$tmp/bin" 2> "$tmp/err"; then exit 1; fi
grep -q "job 0 of seed 5 (network grid, job seed [0-9]*, SUMO seed [0-9]*, attempt 3): step netgenerate: netgenerate failed: exit code 3" "$tmp/err"
grep -q "after 2 failed attempts" "$tmp/err"
grep -q "Error: no memory for the grid" "$tmp/err"
test -z "$(ls -d "$tmp"/scenestreamer-sumo-* 2>/dev/null)"
# An OSM network that cannot be read (SUMO_HOME without the shipped networks).
mkdir -p "$tmp/home/tools"
ln -s /usr/share/sumo/tools/randomTrips.py "$tmp/home/tools/randomTrips.py"
if "$bin" dataset sumo --out "$tmp/c" $small --networks osm --sumo-home "$tmp/home" 2> "$tmp/err"; then exit 1; fi
grep -q "job 0 of seed 5 (network osm, job seed [0-9]*, SUMO seed [0-9]*): step osm source: cannot read $tmp/home/tools/" "$tmp/err"
# Bad arguments, and an output directory that already holds a dataset.
if "$bin" dataset sumo --out "$tmp/c" $small --networks grid,moon 2> "$tmp/err"; then exit 1; fi
grep -q 'unknown kind "moon"' "$tmp/err"
if "$bin" dataset sumo --out "$tmp/c" --seed 1 2> "$tmp/err"; then exit 1; fi
grep -q -- "--scenarios is required" "$tmp/err"
if "$bin" dataset sumo --out "$tmp/a" $small 2> "$tmp/err"; then exit 1; fi
grep -q "already holds a generated dataset" "$tmp/err"
if "$bin" dataset stats "$tmp/nope" 2> "$tmp/err"; then exit 1; fi
grep -q "nope: no such file or directory" "$tmp/err"
