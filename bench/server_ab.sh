#!/bin/sh
# Server throughput, A/B: each round runs every server given, in turn, on one loopback port, under the same load
# (build/client_examples/scenestreamer-load), and prints one JSON line per run: the load generator's figures plus the
# label, the round and the server's peak RSS. Interleaving the builds round by round is what makes their ratio
# meaningful on a machine whose load drifts (docs/performance.md).
#
#   bench/server_ab.sh [-r ROUNDS] [-c CLIENTS] [-s STEPS] [-d DENSIFY] LABEL=SERVER_BINARY[:ENV=VALUE] ...
#
# e.g. bench/server_ab.sh -r 4 A=/tmp/ab-a/build/server/scenestreamer-server C=build/server/scenestreamer-server
# An ENV=VALUE after a colon is set for that server only (LD_PRELOAD=..., MALLOC_CONF=...), except
# LOAD_FLAGS=..., which the load generator gets for that run (LOAD_FLAGS=--no-motion-reject: sessions without reject
# sampling; one server binary can then be compared with itself).
# Every server runs with --threads 2, the trained default model and the real val scenarios, as in docs/performance.md.
set -eu

ROUNDS=4 CLIENTS=32 STEPS=30 DENSIFY=64
while getopts r:c:s:d: opt; do
  case $opt in
    r) ROUNDS=$OPTARG ;;
    c) CLIENTS=$OPTARG ;;
    s) STEPS=$OPTARG ;;
    d) DENSIFY=$OPTARG ;;
    *) echo "usage: $0 [-r ROUNDS] [-c CLIENTS] [-s STEPS] [-d DENSIFY] LABEL=SERVER[:ENV=VALUE] ..." >&2; exit 2 ;;
  esac
done
shift $((OPTIND - 1))
[ $# -ge 1 ] || { echo "$0: give at least one LABEL=SERVER_BINARY" >&2; exit 2; }

ROOT=$(cd "$(dirname "$0")/.." && pwd)
LOAD=${LOAD:-$ROOT/build/client_examples/scenestreamer-load}
MODEL=${MODEL:-$ROOT/models/default.safetensors}
SCENARIOS=${SCENARIOS:-$ROOT/../shared/data/womd/json/val}
PORT=${PORT:-50091}
for f in "$LOAD" "$MODEL"; do [ -e "$f" ] || { echo "$0: $f is missing (build first)" >&2; exit 1; }; done
[ -d "$SCENARIOS" ] || { echo "$0: scenario directory $SCENARIOS is missing" >&2; exit 1; }
for spec in "$@"; do
  bin=${spec#*=}; bin=${bin%%:*}
  [ -x "$bin" ] || { echo "$0: server $bin (from '$spec') is not an executable" >&2; exit 1; }
done

TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT

# Peak RSS in kB of process $1 while it runs, written to $2 when it ends.
watch_rss() {
  peak=0
  while [ -r "/proc/$1/status" ]; do
    now=$(awk '/^VmHWM:/ {print $2}' "/proc/$1/status" 2>/dev/null || echo 0)
    [ -n "$now" ] && [ "$now" -gt "$peak" ] && peak=$now
    sleep 0.5
  done
  echo "$peak" > "$2"
}

round=1
while [ "$round" -le "$ROUNDS" ]; do
  for spec in "$@"; do
    label=${spec%%=*}
    rest=${spec#*=}
    bin=${rest%%:*}
    envs="" load_flags=""
    [ "$rest" != "$bin" ] && envs=${rest#*:}
    case " $envs " in
      *" LOAD_FLAGS="*)
        load_flags=${envs#*LOAD_FLAGS=}; load_flags=${load_flags%% *}
        envs=$(echo "$envs" | sed 's/LOAD_FLAGS=[^ ]*//') ;;
    esac
    # shellcheck disable=SC2086  # envs is a list of NAME=VALUE words
    env $envs "$bin" --host 127.0.0.1 --port "$PORT" --threads 2 --model "$MODEL" --scenario_dir "$SCENARIOS" \
      --metrics_port -1 --log_level warn > "$TMP/server.log" 2>&1 &
    pid=$!
    # Ready when its port accepts a connection (older builds have no health service; gRPC listens once the model and
    # scenarios are loaded).
    i=0
    until /usr/bin/python3 -c 'import socket, sys; socket.create_connection(("127.0.0.1", int(sys.argv[1])), 1)' \
        "$PORT" 2> /dev/null; do
      i=$((i + 1))
      if [ "$i" -gt 300 ] || ! kill -0 "$pid" 2> /dev/null; then
        echo "$0: server $label did not come up:" >&2; cat "$TMP/server.log" >&2; kill "$pid" 2> /dev/null; exit 1
      fi
      sleep 0.1
    done
    watch_rss "$pid" "$TMP/rss" &
    watcher=$!
    # The server's CPU time (user + system, clock ticks) over the load alone: a machine whose spare capacity drifts
    # moves steps/s more than the CPU time each step costs.
    cpu0=$(awk '{print $14 + $15}' "/proc/$pid/stat")
    # shellcheck disable=SC2086  # load_flags is a list of words
    "$LOAD" --clients "$CLIENTS" --steps "$STEPS" --densify "$DENSIFY" --target "127.0.0.1:$PORT" --json $load_flags \
      > "$TMP/load.json" || true
    cpu1=$(awk '{print $14 + $15}' "/proc/$pid/stat" 2> /dev/null || echo none)  # none: the server had ended
    kill -TERM "$pid"
    wait "$pid" || true
    wait "$watcher"
    /usr/bin/python3 -c '
import json, sys
out = {"label": sys.argv[1], "round": int(sys.argv[2]), "load_average": float(open("/proc/loadavg").read().split()[0])}
out.update(json.load(open(sys.argv[3])))
out["server_peak_rss_mb"] = int(open(sys.argv[4]).read()) / 1000
steps = out["clients"] * out["steps"]
cpu_s = None if sys.argv[6] == "none" else (int(sys.argv[6]) - int(sys.argv[5])) / int(sys.argv[7])
out["server_cpu_ms_per_step"] = None if cpu_s is None or steps == 0 else 1000 * cpu_s / steps
print(json.dumps(out))' "$label" "$round" "$TMP/load.json" "$TMP/rss" "$cpu0" "$cpu1" "$(getconf CLK_TCK)" \
      | tee -a "$TMP/runs.jsonl"
  done
  round=$((round + 1))
done

# The summary, on stderr: each label's median steps/s and CPU time per step and their ratios to the first label's,
# errors summed.
/usr/bin/python3 - "$TMP/runs.jsonl" >&2 <<'PY'
import json, statistics, sys
runs = [json.loads(line) for line in open(sys.argv[1])]
labels = list(dict.fromkeys(r["label"] for r in runs))
med = {l: statistics.median(r["steps_per_second"] for r in runs if r["label"] == l) for l in labels}
cpu = {l: statistics.median([r["server_cpu_ms_per_step"] for r in runs if r["label"] == l
                              and r["server_cpu_ms_per_step"] is not None] or [float("nan")]) for l in labels}
for l in labels:
    mine = [r for r in runs if r["label"] == l]
    rates = ", ".join("%.1f" % r["steps_per_second"] for r in mine)
    p50 = statistics.median(r["latency_ms_p50"] for r in mine)
    p99 = statistics.median(r["latency_ms_p99"] for r in mine)
    rss = [r["server_peak_rss_mb"] for r in mine]
    print(f"{l}: steps/s {rates}; median {med[l]:.1f} ({med[l] / med[labels[0]]:.2f}x {labels[0]}); "
          f"CPU {cpu[l]:.1f} ms/step ({cpu[labels[0]] / cpu[l]:.2f}x); p50 {p50:.0f} ms, p99 {p99:.0f} ms; "
          f"errors {sum(r['errors'] for r in mine)}; "
          f"peak RSS {min(rss):.0f}-{max(rss):.0f} MB")
PY
