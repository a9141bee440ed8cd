#!/bin/sh
# scenestreamer init-weights, run as a user would: determinism, and refusals with exit code 2.
# usage: init_weights_test.sh SCENESTREAMER DATA_DIR
set -eu
bin=$1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

"$bin" init-weights --config small --seed 5 --out "$tmp/a.safetensors" > "$tmp/a.log"
"$bin" init-weights --config small --seed=5 --out "$tmp/b.safetensors" > /dev/null
"$bin" init-weights --config small --seed 6 --out "$tmp/c.safetensors" > /dev/null
cmp "$tmp/a.safetensors" "$tmp/b.safetensors"
! cmp -s "$tmp/a.safetensors" "$tmp/c.safetensors"
size=$(wc -c < "$tmp/a.safetensors")
grep -q "config small, seed 5, [0-9]* parameters, $size bytes" "$tmp/a.log"

for args in "--config medium --out $tmp/x" "--config small" "--config small --out $tmp/x --seed -1" \
            "--config small --out $tmp/x --bogus 1" "--config small --out $tmp/x extra"; do
  status=0
  "$bin" init-weights $args > /dev/null 2> "$tmp/err" || status=$?
  [ "$status" -eq 2 ] || { echo "init-weights $args: exit $status, expected 2"; exit 1; }
  [ -s "$tmp/err" ] || { echo "init-weights $args: no message"; exit 1; }
done
[ ! -e "$tmp/x" ]
echo ok
