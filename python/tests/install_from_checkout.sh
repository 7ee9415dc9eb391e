#!/usr/bin/env bash
# `pip install ./python` from a clean checkout, offline, in a venv, as python/README.md says;
# then the installed package imports its stubs and reads a camera.
# Usage: install_from_checkout.sh PYTHON3 SOURCE_DIR
set -euo pipefail
python=$1
source=$2
work=$(mktemp -d /tmp/visloc_pip.XXXXXX)
trap 'rm -rf "$work"' EXIT
mkdir "$work/checkout"
cp -r "$source/python" "$source/proto" "$source/CMakeLists.txt" "$work/checkout/"
version=$(sed -n 's/^project(visloc VERSION \([0-9.]*\).*/\1/p' "$source/CMakeLists.txt")
# Whatever a developer's build left in the source tree is not a clean checkout...
rm -rf "$work/checkout/python/build" "$work/checkout/python/"*.egg-info \
       "$work/checkout/python/visloc/v1"
# ...except stubs an earlier `pip install` left in python/build from an older proto: they must
# not be packaged in place of the proto's.
mkdir -p "$work/checkout/python/build/lib/visloc/v1"
echo "STALE = True  # an older proto's stubs" > "$work/checkout/python/build/lib/visloc/v1/visloc_pb2.py"
cd "$work/checkout"
"$python" -m venv --system-site-packages "$work/venv"
# The README's command; PIP_NO_INDEX makes sure nothing is fetched.
PIP_NO_INDEX=1 "$work/venv/bin/pip" install -q --no-build-isolation ./python
cd "$work"
printf 'camera_model: pinhole\nresolution: [640, 480]\nintrinsics: [525, 525, 319.5, 239.5]\n' \
  > sensor.yaml
VISLOC_VERSION=$version "$work/venv/bin/python" - <<'PY'
import importlib.metadata
import os
import visloc
from visloc.v1 import visloc_pb2 as pb, visloc_pb2_grpc as pb_grpc
assert "/venv/" in visloc.__file__, visloc.__file__
# One version: the C++ project's.
assert importlib.metadata.version("visloc") == os.environ["VISLOC_VERSION"], \
    (importlib.metadata.version("visloc"), os.environ["VISLOC_VERSION"])
assert pb.STATUS_CLOSED == 8 and hasattr(pb_grpc, "LocalizationStub")
assert not hasattr(pb, "STALE") and pb.MAX_MESSAGE_BYTES == 64 << 20
camera = visloc.camera_from_yaml("sensor.yaml")
assert (camera.width, camera.fx) == (640, 525.0), camera
print("installed from a checkout:", visloc.__file__)
PY
