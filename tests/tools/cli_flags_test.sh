#!/bin/sh
# The command lines of every subcommand (common/command_line.h): --help lists exactly the command's flags with their
# defaults; another command's flag, an unknown flag, a bad number or a missing value is refused with exit code 2 and a
# message naming it. With SS_TRAIN set (tests/CMakeLists.txt, when the trainer is built), scenestreamer-train too.
# usage: cli_flags_test.sh SCENESTREAMER DATA_DIR
set -eu
bin=$1
data=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
scenario="$data/womd/tfrecord/motion_data_one_scenario.tfrecord"

# help PROGRAM_AND_COMMAND... -- FLAG...: --help exits 0 and lists exactly these flags, each with its default.
help() {
  cmd=""
  while [ "$1" != "--" ]; do cmd="$cmd $1"; shift; done
  shift
  # shellcheck disable=SC2086
  $cmd --help > "$tmp/help" 2> "$tmp/err" || { echo "$cmd --help: exit $?" >&2; cat "$tmp/err" >&2; exit 1; }
  grep -q "^usage: " "$tmp/help" || { echo "$cmd --help: no usage" >&2; exit 1; }
  listed=$(sed -n 's/^  --\([a-z0-9-]*\) (default: .*)$/\1/p' "$tmp/help" | sort | tr '\n' ' ')
  expected=$(printf '%s\n' "$@" | sort | tr '\n' ' ')
  [ "$listed" = "$expected" ] || { echo "$cmd --help lists: $listed; expected: $expected" >&2; exit 1; }
}

# refused MESSAGE ARGS...: the command line exits 2 and stderr holds MESSAGE.
refused() {
  msg=$1
  shift
  status=0
  "$@" > /dev/null 2> "$tmp/err" || status=$?
  [ "$status" -eq 2 ] || { echo "$*: exit $status, expected 2" >&2; cat "$tmp/err" >&2; exit 1; }
  grep -qF -- "$msg" "$tmp/err" || { echo "$*: expected '$msg', got:" >&2; cat "$tmp/err" >&2; exit 1; }
}

"$bin" --help | grep -q "dataset sumo|stats"
"$bin" dataset --help | grep -q "stats FILE_OR_DIR"
help "$bin" inspect -- json
help "$bin" convert -- out wosac-submission submission-metadata
help "$bin" init-weights -- config seed out
help "$bin" simulate -- scenario model out mode sdc steps seed rollout index top-p temperature motion-reject max-agents densify-target \
  kv-precision matmul-precision agent-counts placement-room pedestrian-contact
help "$bin" bench -- json model scenario steps long-steps kv-precision matmul-precision motion-reject
help "$bin" render -- scenario index step animate radius out
help "$bin" eval -- data model mode rollouts seed baseline sdc ego json plots threads compare bootstrap wosac-submission \
  submission-metadata submission top-p temperature motion-reject kv-precision matmul-precision protocol roi-radius \
  placement-temperature placement-top-p placement-clearance placement-room pedestrian-contact history
help "$bin" dataset sumo -- out scenarios seed networks radius map-radius workers warmup record egos-per-window \
  shard-size sumo-bin sumo-home python tmp keep-temp first-job quiet
help "$bin" dataset stats -- json markdown
# Defaults are each command's own where two commands share a name.
"$bin" eval --help | grep -q '^  --rollouts (default: 4)$'
"$bin" eval --help | grep -q '^  --json (default: "")$'
"$bin" inspect --help | grep -q '^  --json (default: false)$'
"$bin" bench --help | grep -q '^  --steps (default: 30)$'
"$bin" simulate --help | grep -q '^  --steps (default: -1)$'
"$bin" render --help | grep -q '^  --radius (default: 80)$'
"$bin" dataset sumo --help | grep -q '^  --radius (default: 100)$'

# Another command's flag: each command takes only its own and the shared flags it lists.
refused "unknown flag --long-steps" "$bin" eval --data "$scenario" --baseline cv --json "$tmp/x.json" --long-steps 5
refused "unknown flag --rollouts" "$bin" bench --rollouts 2
refused "unknown flag --markdown" "$bin" inspect --markdown "$scenario"
refused "unknown flag --model" "$bin" render "$scenario" --model w.safetensors
refused "unknown flag --seed" "$bin" dataset stats --seed 1 "$scenario"
# Unknown flags, and the old spelling only: names take dashes, not Abseil's underscores.
refused "unknown flag --bogus" "$bin" inspect --bogus "$scenario"
refused "unknown flag --top_p" "$bin" eval --data "$scenario" --json "$tmp/x.json" --top_p 0.5
# Bad numbers: Abseil's error names the flag and the value.
refused "Illegal value 'abc' specified for flag 'rollouts'" \
  "$bin" eval --data "$scenario" --baseline cv --json "$tmp/x.json" --rollouts abc
refused "Illegal value '1.5' specified for flag 'rollouts'" \
  "$bin" eval --data "$scenario" --baseline cv --json "$tmp/x.json" --rollouts=1.5
refused "--top-p: Illegal value 'high'" "$bin" simulate --scenario "$scenario" --out "$tmp/x.tfrecord" --top-p high
refused "--steps: Illegal value 'zero'" "$bin" bench --steps zero
refused "Illegal value '-1' specified for flag 'seed'" "$bin" init-weights --config small --out "$tmp/x" --seed -1
refused "--json: Illegal value 'maybe'" "$bin" inspect --json=maybe "$scenario"
refused "--out needs a value" "$bin" convert "$scenario" --out
# A command that takes no files refuses a stray argument (one rule, in common/command_line.cc).
refused "unexpected argument 'stray'" "$bin" bench stray
refused "unexpected argument 'stray'" "$bin" init-weights --config small --out "$tmp/x" stray
refused "unexpected argument 'stray'" "$bin" dataset sumo stray --out "$tmp/s" --scenarios 1 --seed 1
# Range checks about meaning stay, with their messages.
refused "--steps must be at least 1" "$bin" bench --steps 0
refused "--scenarios: want a positive integer" "$bin" dataset sumo --out "$tmp/s" --scenarios 0 --seed 1
test ! -e "$tmp/x.json" && test ! -e "$tmp/x.tfrecord" && test ! -e "$tmp/x"

# Positional arguments anywhere, "--" ends the flags, and a value may start with a dash (--out -: stdout).
"$bin" render --step 3 "$scenario" --out - > "$tmp/a.svg"
grep -q "frame 3/90" "$tmp/a.svg"
"$bin" inspect --json -- "$scenario" | grep -q '"scenario_id"'

if [ -n "${SS_TRAIN:-}" ]; then
  help "$SS_TRAIN" -- config data synthetic val out resume real-fraction steps stage1-steps batch lr warmup \
    weight-decay clip max-agents max-map-segments seed threads log-every val-every val-scenarios checkpoint-every \
    eval-every eval-tool eval-scenarios stop-after init-from catk scene-end-weight placement-weight
  help "$SS_TRAIN" export -- checkpoint out
  help "$SS_TRAIN" plot -- run out
  refused "unknown flag --checkpoint" "$SS_TRAIN" --checkpoint x --out "$tmp/run"
  refused "unknown flag --resume" "$SS_TRAIN" export --checkpoint x --out "$tmp/m" --resume
  refused "Illegal value 'many' specified for flag 'steps'" "$SS_TRAIN" --steps many --out "$tmp/run"
  refused "Illegal value 'x' specified for flag 'catk'" "$SS_TRAIN" --catk x --out "$tmp/run"
  # A bad value the trainer checks itself (exit 1, as for every run error), before it writes anything.
  if "$SS_TRAIN" --placement-weight 0 --data "$scenario" --out "$tmp/run" 2> "$tmp/err"; then exit 1; fi
  grep -qF -- "--placement-weight 0 must be positive" "$tmp/err"
  refused "--checkpoint and --out are required" "$SS_TRAIN" export --out "$tmp/m"
  test ! -e "$tmp/run" && test ! -e "$tmp/m"
fi
echo "cli_flags_test: ok"
