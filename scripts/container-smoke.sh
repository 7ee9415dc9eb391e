#!/usr/bin/env bash
# Builds the container image for real and tests it, without a container daemon (opt-in: slow,
# needs root; not part of CI). Debian's podman builds docker/Dockerfile from a debootstrapped
# debian:bookworm base; the built image's filesystem is exported and its server started from
# it with chroot as the image's non-root user, on a loopback port. The host's `visloc` then
# uploads a map into it and streams the demo's kidnap sequence through it.
# Usage: scripts/container-smoke.sh [WORK=out/container-smoke]
# Prints the figures docs/deployment.md quotes and keeps them in WORK/summary.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
work=$(realpath -m "${1:-out/container-smoke}")
image=localhost/visloc:smoke
mkdir -p "$work"
[ "$(id -u)" -eq 0 ] || { echo "container-smoke: needs root (debootstrap, chroot)"; exit 1; }
for tool in podman debootstrap; do
  command -v "$tool" > /dev/null || { apt-get install -y -qq podman debootstrap uidmap > /dev/null; break; }
done
bash scripts/build.sh  # The host's client and a release build to compare with.
podman_() { podman --cgroup-manager=cgroupfs "$@"; }
summary="$work/summary.txt"
: > "$summary"
note() { echo "$*" | tee -a "$summary"; }

echo "== 1. The base image: debian:bookworm from debootstrap (no registry here)"
if ! podman_ image exists docker.io/library/debian:bookworm; then
  rm -rf "$work/rootfs-base"
  debootstrap --variant=minbase bookworm "$work/rootfs-base" > "$work/debootstrap.log"
  # As Debian's official image: no package lists or downloaded packages in the base.
  rm -rf "$work/rootfs-base"/var/lib/apt/lists/* "$work/rootfs-base"/var/cache/apt/*
  tar -C "$work/rootfs-base" -c . | podman_ import - localhost/bookworm-base > /dev/null
  podman_ tag localhost/bookworm-base docker.io/library/debian:bookworm
  rm -rf "$work/rootfs-base"
fi

echo "== 2. podman build -f docker/Dockerfile (log: $work/build.log)"
start=$(date +%s)
podman_ build --format docker --pull=never --isolation chroot --network host \
  -f docker/Dockerfile -t "$image" . > "$work/build.log" 2>&1 || { tail -30 "$work/build.log"; exit 1; }
note "build: $(( $(date +%s) - start )) s (from scratch unless podman cached layers)"
note "image: $(podman_ image inspect --format '{{.Size}}' "$image" | awk '{printf "%.0f MB", $1 / 1e6}') (base $(podman_ image inspect --format '{{.Size}}' docker.io/library/debian:bookworm | awk '{printf "%.0f MB", $1 / 1e6}'))"
note "$(grep 'collect-runtime:' "$work/build.log" | tail -1)"
note "user: $(podman_ image inspect --format '{{.Config.User}}' "$image"); entrypoint: $(podman_ image inspect --format '{{.Config.Entrypoint}} {{.Config.Cmd}}' "$image")"
note "healthcheck: $(podman_ image inspect --format '{{.Config.Healthcheck.Test}}' "$image")"

echo "== 3. The image's filesystem, exported"
root="$work/rootfs"
# Nothing is ever mounted under $root; if something is (an earlier run of an older script),
# deleting it would delete through the mount, so refuse.
if grep -q " $root/" /proc/self/mounts 2> /dev/null; then
  echo "container-smoke: something is mounted under $root; unmount it first"; exit 1
fi
rm -rf "$root" && mkdir -p "$root"
container=$(podman_ create "$image")
podman_ export "$container" | tar -C "$root" -x
podman_ rm "$container" > /dev/null 2>&1  # (podman warns that no systemd timer exists)
uid=$(chroot "$root" id -u visloc) gid=$(chroot "$root" id -g visloc)
[ "$uid" -ne 0 ] || { echo "the image's user is root"; exit 1; }
# The few device nodes a container runtime would give it; no host mounts.
for node in "null 1 3" "zero 1 5" "random 1 8" "urandom 1 9"; do
  set -- $node
  rm -f "$root/dev/$1" && mknod -m 666 "$root/dev/$1" c "$2" "$3"
done
server_pid=
cleanup() {
  if [ -n "$server_pid" ]; then kill -TERM "$server_pid" 2> /dev/null || true; fi
}
trap cleanup EXIT
# Tokens as a Kubernetes secret would mount them; the maps volume owned by the image's user.
robot_token=$(openssl rand -hex 16) admin_token=$(openssl rand -hex 16)
printf '%s localize\n%s admin\n' "$robot_token" "$admin_token" > "$root/etc/visloc/tokens"
as_visloc() { chroot --userspec="$uid:$gid" "$root" env HOME=/var/lib/visloc "$@"; }

echo "== 4. visloc-server from the image, as uid $uid, on loopback"
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
# chroot execs the server: $! is the server itself, which the SIGTERM below must reach.
chroot --userspec="$uid:$gid" "$root" visloc-server --maps /maps --listen "127.0.0.1:$port" \
  --tokens /etc/visloc/tokens > "$work/server.out" 2> "$work/server.log" &
server_pid=$!
for _ in $(seq 100); do grep -q "listening on" "$work/server.out" 2> /dev/null && break; sleep 0.1; done
grep -q "listening on" "$work/server.out" || { cat "$work/server.log"; exit 1; }
address=127.0.0.1:$port
as_visloc visloc health --server "$address" | tee -a "$summary"

echo "== 5. A map built on the host, uploaded into the container's volume, a kidnap streamed"
data="$work/data"
if [ ! -f "$data/square.db" ]; then
  build/client/visloc sim --out "$data" --sequence map_square,kidnap > /dev/null
  build/client/visloc map build --dataset "$data/map_square" --out "$data/square.db" > /dev/null
fi
VISLOC_TOKEN=$admin_token build/client/visloc map upload "$data/square.db" --server "$address" --replace
note "uploaded: $(stat -c 'owner uid %u, %s bytes' "$root/maps/square.db") in the image's /maps"
VISLOC_TOKEN=$robot_token build/client/visloc stream --server "$address" --map square \
  --dataset "$data/kidnap" --trajectory "$work/kidnap.tum" --stats "$work/kidnap.csv" \
  --gt "$data/kidnap/groundtruth_map.tum" --json > "$work/stream.json"
note "stream: $(cat "$work/stream.json")"
note "eval: $(build/client/visloc eval --gt "$data/kidnap/groundtruth_map.tum" --est "$work/kidnap.tum" --json)"
refused=$(VISLOC_TOKEN=$robot_token build/client/visloc map delete square --server "$address" 2>&1 || true)
note "robot token deleting a map: $refused"

echo "== 6. The compose demo's client, from the image, against the same server (log: $work/demo-client.log)"
start=$(date +%s)
as_visloc VISLOC_TOKEN="$admin_token" VISLOC_DEMO_OUT=/var/lib/visloc/demo \
  visloc-demo-client "$address" > "$work/demo-client.log" 2>&1 || { tail -20 "$work/demo-client.log"; exit 1; }
note "demo client: passed in $(( $(date +%s) - start )) s; its last lines:"
tail -n 8 "$work/demo-client.log" | sed 's/^/  /' | tee -a "$summary"

echo "== 7. SIGTERM drains"
kill -TERM "$server_pid"
status=0
wait "$server_pid" || status=$?
server_pid=
note "server exit: $status"
tail -n 1 "$work/server.log" | tee -a "$summary"
echo "container-smoke: passed; figures in $summary"
