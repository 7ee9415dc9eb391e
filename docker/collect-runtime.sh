#!/usr/bin/env bash
# Runs in the image's builder stage. Stages the binaries and every shared library they load
# that the runtime base image lacks under STAGE/, so the runtime stage is one COPY of plain
# files onto debian:bookworm with no build tools and no -dev packages.
# Usage: collect-runtime.sh STAGE BASE_PACKAGES.txt BINARY...
#   BASE_PACKAGES.txt: `dpkg-query -W -f='${Package}\n'` of the bare base image, recorded
#   before anything was installed: libraries of those packages are already in the runtime
#   image (and get its security updates), so they are not copied.
# Also copies each source package's copyright file, as Debian's licences ask.
set -euo pipefail
stage=$1 base_packages=$2
shift 2
mkdir -p "$stage/usr/local/bin" "$stage/usr/local/lib/visloc" "$stage/usr/share/doc"
for binary in "$@"; do
  install -m 0755 -s "$binary" "$stage/usr/local/bin/"
done
# ldd lists the whole closure (libraries of libraries); "=> not found" would be a broken build.
if ldd "$@" | grep -q "not found"; then ldd "$@" | grep "not found"; exit 1; fi
copied=0
for lib in $(ldd "$@" | awk '/=> \// {print $3}' | sort -u); do
  package=$(dpkg -S "$(readlink -f "$lib")" 2>/dev/null | head -1 | cut -d: -f1) || true
  [ -n "$package" ] || package=$(dpkg -S "$lib" | head -1 | cut -d: -f1)
  if grep -qx "$package" "$base_packages"; then continue; fi
  cp -L "$lib" "$stage/usr/local/lib/visloc/"
  copied=$((copied + 1))
  if [ -f "/usr/share/doc/$package/copyright" ] && [ ! -e "$stage/usr/share/doc/$package" ]; then
    mkdir -p "$stage/usr/share/doc/$package"
    cp "/usr/share/doc/$package/copyright" "$stage/usr/share/doc/$package/"
  fi
done
echo /usr/local/lib/visloc > "$stage/visloc-ld.conf"
echo "collect-runtime: $# binaries, $copied libraries ($(du -sh "$stage/usr/local/lib/visloc" | cut -f1))"
