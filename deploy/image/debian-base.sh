#!/bin/sh
# Makes the debian:bookworm base image locally, for machines that reach the Debian archive but no image registry:
# debootstrap (minbase) from the archive apt already uses, its root file system committed by buildah under the name
# the Dockerfile's FROM resolves to (docker.io/library/debian:bookworm). Skipped when that image exists.
# Usage: deploy/image/debian-base.sh [MIRROR]   (default: the first Debian URI of apt's own sources)
set -eu

IMAGE=docker.io/library/debian:bookworm
if buildah inspect --type image "$IMAGE" >/dev/null 2>&1; then
  echo "debian-base: $IMAGE already present"
  exit 0
fi

mirror="${1:-}"
if [ -z "$mirror" ]; then
  mirror=$(sed -n 's/^URIs:[[:space:]]*\([^[:space:]]*\/debian\)[[:space:]]*$/\1/p' \
             /etc/apt/sources.list.d/*.sources 2>/dev/null | head -n 1)
fi
if [ -z "$mirror" ]; then
  mirror=$(sed -n 's/^deb[[:space:]]\+\([^[:space:]]*\/debian\)[[:space:]]\+bookworm[[:space:]].*/\1/p' \
             /etc/apt/sources.list 2>/dev/null | head -n 1)
fi
if [ -z "$mirror" ]; then
  echo "debian-base: no Debian mirror in apt's sources; pass one: $0 http://deb.debian.org/debian" >&2
  exit 1
fi

work=$(mktemp -d /var/tmp/debian-base.XXXXXX)
trap 'rm -rf "$work"' EXIT
echo "debian-base: debootstrap bookworm from $mirror"
debootstrap --variant=minbase bookworm "$work/rootfs" "$mirror"
# The image's own apt reads the same archive, and its -security sibling (as deb.debian.org serves it) like the
# official image; no package caches or lists are kept in the base.
keyring=/usr/share/keyrings/debian-archive-keyring.gpg
{
  printf 'Types: deb\nURIs: %s\nSuites: bookworm bookworm-updates\nComponents: main\nSigned-By: %s\n\n' "$mirror" "$keyring"
  printf 'Types: deb\nURIs: %s-security\nSuites: bookworm-security\nComponents: main\nSigned-By: %s\n' "$mirror" "$keyring"
} > "$work/rootfs/etc/apt/sources.list.d/debian.sources"
rm -f "$work/rootfs/etc/apt/sources.list"
rm -rf "$work/rootfs/var/lib/apt/lists/"* "$work/rootfs/var/cache/apt/archives/"*.deb
tar -C "$work/rootfs" -cf "$work/rootfs.tar" .

ctr=$(buildah from scratch)
buildah add "$ctr" "$work/rootfs.tar" /
buildah config --cmd /bin/bash --env PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin "$ctr"
buildah commit --rm "$ctr" "$IMAGE"
echo "debian-base: committed $IMAGE"
