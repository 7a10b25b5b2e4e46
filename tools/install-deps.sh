#!/usr/bin/env bash
# Installs every Debian package sfrt needs to build, test and run (Debian bookworm, as root).
# Idempotent: prints nothing and changes nothing when all packages are present.
set -euo pipefail

packages=(
  # build
  build-essential cmake pkg-config clang-format
  # runtime core: model file schema
  flatbuffers-compiler libflatbuffers-dev libeigen3-dev
  # exporter: ONNX, Keras HDF5 (+ JSON for its model_config)
  libonnx-dev libprotobuf-dev protobuf-compiler libhdf5-dev
  # command-line tool, cameras, image I/O, deployment profiles
  libopencv-dev libcli11-dev nlohmann-json3-dev libturbojpeg0-dev libyaml-cpp-dev libdeflate-dev
  # aarch64 cross build of the runtime, tested under qemu
  g++-aarch64-linux-gnu qemu-user
  # tests, benchmarks, fuzzing (libFuzzer comes with clang's runtime) and memcheck
  libgtest-dev libgmock-dev libbenchmark-dev clang-14 libclang-rt-14-dev valgrind
  # reference models for tests (PyTorch builds SceneEDNet and exports ONNX)
  python3 python3-numpy python3-torch python3-onnx python3-h5py python3-pil python3-flatbuffers
  # the Python package (python/: pybind11 against Debian's python3), its tests and examples
  python3-dev pybind11-dev python3-pybind11 python3-pytest python3-matplotlib
  # the KITTI tests' PNG decoder, independent of OpenCV and libpng (pure Python)
  python3-png
  # sharded evaluation on a real scheduler: the suite starts a single-node Slurm on loopback
  slurm-wlm
  # ROS 1 as Debian packages it: bag replay (ros/), the sfrt_ros node, and the master, rosbag
  # play and Python clients its tests use
  librosbag-dev libsensor-msgs-dev python3-rosbag python3-sensor-msgs
  libroscpp-dev libimage-transport-dev libmessage-filters-dev libcv-bridge-dev
  libdiagnostic-msgs-dev ros-core python3-rospy python3-diagnostic-msgs
  # ROS 2 without rclcpp (ros2/): rosbag2's storages (MCAP chunks in zstd or lz4, sqlite3), the
  # DDS ROS 2 runs on (Cyclone DDS for sfrt_ros2; Fast DDS for a test participant of another
  # vendor)
  libzstd-dev liblz4-dev libsqlite3-dev python3-yaml cyclonedds-dev cyclonedds-tools
  libfastrtps-dev libfastcdr-dev
)

# Node.js runs the tests' independent implementations (tests/npm: the MCAP and ROS 2 CDR
# oracles). Any node >= 18 with npm will do (Debian's nodejs and npm, or NodeSource's nodejs,
# which brings npm).
command -v node >/dev/null && command -v npm >/dev/null || packages+=(nodejs npm)

missing=()
for p in "${packages[@]}"; do
  status=$(dpkg-query -W -f='${db:Status-Abbrev}' "$p" 2>/dev/null || true)
  [[ "$status" == ii* ]] || missing+=("$p")
done
[[ ${#missing[@]} -eq 0 ]] && exit 0

echo "install-deps: installing ${#missing[@]} package(s): ${missing[*]}"
sudo_cmd=()
[[ $(id -u) -eq 0 ]] || sudo_cmd=(sudo)
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done"
