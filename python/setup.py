"""Builds the visloc package with its visloc.v1 stubs (the metadata is in pyproject.toml).

The stubs are generated from the repository's proto/visloc/v1/visloc.proto at build time, so
``pip install --no-build-isolation ./python`` works from a clean checkout. Generated with
Debian's protoc and grpc_python_plugin (protobuf-compiler, protobuf-compiler-grpc), or with
grpcio-tools when that is what is installed. A tree that already holds the stubs (CMake's
build/python) is packaged as it is.
"""

import os
import re
import shutil
import subprocess
import sys

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = os.path.dirname(os.path.abspath(__file__))
PROTO = "visloc/v1/visloc.proto"


def proto_dir() -> str:
    candidates = [os.environ.get("VISLOC_PROTO_DIR", ""), os.path.join(HERE, "..", "proto"),
                  os.path.join(HERE, "proto")]
    for candidate in candidates:
        if candidate and os.path.isfile(os.path.join(candidate, PROTO)):
            return os.path.abspath(candidate)
    sys.exit(f"visloc: cannot find {PROTO} beside python/ (a checkout's proto/ folder), "
             "nor in $VISLOC_PROTO_DIR")


def project_version() -> str:
    """visloc's one version: project(visloc VERSION x.y.z) in the checkout's CMakeLists.txt, or
    the VERSION file CMake writes beside this file in build/python."""
    path = os.path.join(HERE, "..", "CMakeLists.txt")
    if os.path.isfile(os.path.join(HERE, "VERSION")):
        with open(os.path.join(HERE, "VERSION"), encoding="utf-8") as f:
            return f.read().strip()
    try:
        with open(path, encoding="utf-8") as f:
            found = re.search(r"project\(visloc VERSION ([0-9.]+)", f.read())
    except OSError:
        found = None
    if not found:
        sys.exit(f"visloc: cannot read the version from {os.path.abspath(path)} "
                 "(install from a checkout: python/ beside CMakeLists.txt and proto/)")
    return found.group(1)


def protoc_command(proto_path: str, out: str) -> list:
    outputs = [f"--proto_path={proto_path}", f"--python_out={out}", f"--grpc_python_out={out}",
               os.path.join(proto_path, PROTO)]
    protoc, plugin = shutil.which("protoc"), shutil.which("grpc_python_plugin")
    if protoc and plugin:
        return [protoc, f"--plugin=protoc-gen-grpc_python={plugin}"] + outputs
    try:
        import grpc_tools  # noqa: F401
        return [sys.executable, "-m", "grpc_tools.protoc"] + outputs
    except ImportError:
        sys.exit("visloc: generating the visloc.v1 stubs needs protoc and grpc_python_plugin "
                 "(apt-get install protobuf-compiler protobuf-compiler-grpc) or grpcio-tools")


class BuildWithStubs(build_py):
    def run(self):
        super().run()
        if os.path.isfile(os.path.join(HERE, "visloc", "v1", "visloc_pb2.py")):
            return  # Packaged from a tree that has them (CMake's build/python).
        # Always generated afresh: stubs a previous build left in build/ may be of an older proto.
        stubs = os.path.join(self.build_lib, "visloc", "v1")
        os.makedirs(stubs, exist_ok=True)
        subprocess.run(protoc_command(proto_dir(), self.build_lib), check=True)
        open(os.path.join(stubs, "__init__.py"), "a").close()


packages = ["visloc"]
if os.path.isfile(os.path.join(HERE, "visloc", "v1", "visloc_pb2.py")):
    packages.append("visloc.v1")
setup(version=project_version(), packages=packages, cmdclass={"build_py": BuildWithStubs})
