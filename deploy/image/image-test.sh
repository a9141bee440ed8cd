#!/bin/sh
# `make image-test`: runs the image's server (buildah run, chroot isolation, host network, a loopback port, as the
# image's non-root user) and drives it with the load generator and the image's own health probe; then SIGTERM, which
# must drain and exit 0.
# Usage: deploy/image/image-test.sh IMAGE LOAD_GENERATOR [PORT]
set -eu

IMAGE=$1
LOAD=$2
PORT=${3:-50151}
work=$(mktemp -d /tmp/ss-image-test.XXXXXX)
server_ctr=""
probe_ctr=""
# The server runs under `buildah run` (buildah-chroot-runtime, then buildah-chroot-exec), as the image's user; a
# signal to buildah itself does not reach it.
find_server() {
  level=$1
  for _ in 1 2 3 4; do
    level=$(ps -o pid= --ppid "$level" | tr -d ' ' | head -n 1)
    [ -n "$level" ] || return 1
    case "$(ps -o args= -p "$level")" in /usr/local/bin/scenestreamer-server*) echo "$level"; return 0 ;; esac
  done
  return 1
}
cleanup() {
  if [ -n "${buildah_pid:-}" ] && pid=$(find_server "$buildah_pid"); then kill -TERM "$pid" 2>/dev/null || true; fi
  [ -n "${buildah_pid:-}" ] && wait "$buildah_pid" 2>/dev/null || true
  [ -n "$server_ctr" ] && buildah rm "$server_ctr" >/dev/null 2>&1 || true
  [ -n "$probe_ctr" ] && buildah rm "$probe_ctr" >/dev/null 2>&1 || true
  rm -rf "$work"
}
trap cleanup EXIT

fail() {
  echo "image-test: FAILED: $*" >&2
  echo "--- server log ---" >&2
  cat "$work/server.log" >&2 || true
  exit 1
}

echo "image-test: $IMAGE, $(buildah images --format '{{.Size}}' "$IMAGE") (buildah's figure)"
server_ctr=$(buildah from --pull=never "$IMAGE")
probe_ctr=$(buildah from --pull=never "$IMAGE")
probe() { buildah run --isolation chroot --network host "$probe_ctr" -- scenestreamer-health --target "127.0.0.1:$PORT"; }
! probe > /dev/null 2>&1 || fail "something already answers on 127.0.0.1:$PORT (pass another port)"

# The image's own command with a loopback address and free ports instead of 0.0.0.0:50051 and 9464.
buildah run --isolation chroot --network host "$server_ctr" -- scenestreamer-server --host=127.0.0.1 --port="$PORT" \
  --metrics_port=-1 --snapshot_dir=/srv/scenestreamer/snapshots > "$work/server.log" 2>&1 &
buildah_pid=$!

i=0
until probe > "$work/probe.log" 2>&1; do
  i=$((i + 1))
  kill -0 "$buildah_pid" 2>/dev/null || fail "the server exited before it was healthy"
  [ "$i" -lt 120 ] || fail "not healthy after 120 probes: $(cat "$work/probe.log")"
  sleep 1
done
echo "image-test: health: $(cat "$work/probe.log") after $i retries"
grep -q "serving scenestreamer.v1.Simulator on 127.0.0.1:$PORT" "$work/server.log" || fail "no serving line"

"$LOAD" --clients 8 --steps 20 --target "127.0.0.1:$PORT" --json > "$work/load.json" || fail "load: $(cat "$work/load.json")"
echo "image-test: load: $(cat "$work/load.json")"
# Read as JSON, not by its spacing (the compact writer prints "errors":0).
/usr/bin/python3 -c 'import json, sys; sys.exit(json.load(open(sys.argv[1]))["errors"] != 0)' "$work/load.json" ||
  fail "load generator saw errors"
probe > "$work/probe.log" 2>&1 || fail "unhealthy after the load: $(cat "$work/probe.log")"

server_pid=$(find_server "$buildah_pid") || fail "no scenestreamer-server process under buildah run ($buildah_pid)"
user=$(ps -o user= -p "$server_pid" | tr -d ' ')
[ "$user" != root ] || fail "the server runs as root"
echo "image-test: server pid $server_pid runs as '$user'"

kill -TERM "$server_pid"
status=0
wait "$buildah_pid" || status=$?
buildah_pid=""
[ "$status" -eq 0 ] || fail "the server exited $status after SIGTERM"
grep -q "stopped" "$work/server.log" || fail "no clean stop in the log"
echo "image-test: SIGTERM: drained, $(grep -o 'saved [0-9]* sessions' "$work/server.log"), exit 0"
echo "image-test: passed"
