#!/bin/sh
# scenestreamer render, run as a user would on the real WOMD files (read in place from ../shared; the pictures are
# written to a temporary directory and deleted: renders of WOMD data never enter the repository).
# usage: render_test.sh SCENESTREAMER DATA_DIR
set -eu
bin=$(cd "$(dirname "$1")" && pwd)/$(basename "$1")  # absolute: one run changes directory
data=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
tfrecord="$data/womd/tfrecord/motion_data_one_scenario.tfrecord"
json="$data/womd/json/val/womd_27d205cc.json"

well_formed() {
  if command -v xmllint > /dev/null; then
    xmllint --noout "$1"
  else
    /usr/bin/python3 -c "import sys, xml.dom.minidom; xml.dom.minidom.parse(sys.argv[1])" "$1"
  fi
}
to_png() {  # rsvg-convert (Debian librsvg2-bin) draws it; skipped where it is not installed
  if command -v rsvg-convert > /dev/null; then
    rsvg-convert "$1" -o "$1.png"
    test "$(head -c 4 "$1.png" | od -An -c | tr -d ' ')" = '211PNG'
  fi
}

# A still of the current frame, written under the scenario's id by default.
(cd "$tmp" && "$bin" render "$tfrecord" 2> "$tmp/log")
grep -q "wrote 637f20cafde22ff8.svg" "$tmp/log"
well_formed "$tmp/637f20cafde22ff8.svg"
grep -q 'id="map"' "$tmp/637f20cafde22ff8.svg"
grep -q 'class="agent vehicle sdc"' "$tmp/637f20cafde22ff8.svg"
grep -q 'frame 10/90' "$tmp/637f20cafde22ff8.svg"
to_png "$tmp/637f20cafde22ff8.svg"

# Another frame, a smaller view, the scenario picked by id and by index.
"$bin" render "$tfrecord" --scenario 637f20cafde22ff8 --step 90 --radius 40 --out "$tmp/last.svg"
grep -q 'viewBox="-40 -40 80 80"' "$tmp/last.svg"
grep -q 'frame 90/90' "$tmp/last.svg"
"$bin" render "$tfrecord" --index=0 --out - > "$tmp/stdout.svg"
head -c 5 "$tmp/stdout.svg" | grep -q '<?xml'
well_formed "$tmp/stdout.svg"

# An animation of a GPUDrive JSON scenario with lights; and of the TFRecord, whose size stays modest.
"$bin" render "$json" --animate --out "$tmp/anim.svg"
well_formed "$tmp/anim.svg"
grep -q '<animateTransform' "$tmp/anim.svg"
grep -q 'attributeName="fill"' "$tmp/anim.svg"  # lights change colour
to_png "$tmp/anim.svg"
"$bin" render "$tfrecord" --animate --out "$tmp/anim2.svg"
test "$(wc -c < "$tmp/anim2.svg")" -lt 3000000

# Errors: a clear message naming what is wrong, a non-zero exit, and no picture.
fails() {  # fails EXPECTED_MESSAGE ARGS...
  msg=$1
  shift
  if "$bin" render "$@" 2> "$tmp/err"; then echo "render $* should fail" >&2; exit 1; fi
  grep -qF -- "$msg" "$tmp/err" || { echo "render $*: expected '$msg', got:" >&2; cat "$tmp/err" >&2; exit 1; }
}
fails "step 91 is outside scenario 637f20cafde22ff8" "$tfrecord" --step 91 --out "$tmp/x.svg"
fails "--step: Illegal value 'soon'" "$tfrecord" --step soon --out "$tmp/x.svg"
fails "bad --radius '-3'" "$tfrecord" --radius -3 --out "$tmp/x.svg"
fails "not both" "$tfrecord" --step 3 --animate --out "$tmp/x.svg"
fails "unknown scenario id 'nope'" "$tfrecord" --scenario nope --out "$tmp/x.svg"
fails "--index 1 is outside" "$tfrecord" --index 1 --out "$tmp/x.svg"
fails "unknown flag --colour" "$tfrecord" --colour red
fails "missing.tfrecord" "$tmp/missing.tfrecord" --out "$tmp/x.svg"
fails "cannot write $tmp/no/such/dir/x.svg" "$tfrecord" --out "$tmp/no/such/dir/x.svg"
test ! -e "$tmp/x.svg"
echo "render_test: ok"
