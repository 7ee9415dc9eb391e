#!/usr/bin/env bash
# Installs everything visloc needs to build, test and run on Debian 12 (bookworm).
# Idempotent and non-interactive: packages already present are skipped, so a second
# run costs only the dpkg query.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git curl bc
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
  libeigen3-dev libopencv-dev libceres-dev libsqlite3-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  sqlite3 libyaml-cpp-dev zlib1g-dev openssl
  libcpp-httplib-dev python3-prometheus-client  # the server's HTTP probes and metrics; its test
  chromium chromium-driver python3-selenium  # the operator page's test in a real browser
  opencv-doc  # OpenCV's stereo chessboard images and stereo_calib sample: calibration's reference
  python3 python3-grpcio python3-protobuf python3-opencv python3-numpy  # the Python client
  python3-pip python3-setuptools python3-venv  # ...installed from the checkout by its test
  # ROS 1 (Debian's own packages): bag import, visloc_ros_node, and ROS's tools for their tests.
  libroscpp-dev librosbag-dev libimage-transport-dev libtf2-ros-dev libsensor-msgs-dev
  libnav-msgs-dev libgeometry-msgs-dev libdiagnostic-msgs-dev libstd-srvs-dev pluginlib-dev
  librcpputils-dev ros-core python3-rosbag python3-rostest python3-sensor-msgs
  python3-nav-msgs python3-geometry-msgs python3-diagnostic-msgs python3-std-srvs
  python3-tf2-msgs python3-yaml
)
# scripts/fuzz.sh needs clang and its libFuzzer / sanitizer runtimes: `install-deps.sh --fuzz`.
if [ "${1:-}" = "--fuzz" ]; then PACKAGES+=(clang libclang-rt-dev); fi

missing=()
for pkg in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$pkg")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done"
