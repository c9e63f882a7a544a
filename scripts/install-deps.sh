#!/usr/bin/env bash
# Installs the Debian 12 packages augrig needs to build, run and test.
# Idempotent: asks dpkg first and only calls apt-get for what is missing.
set -euo pipefail

PACKAGES=(
  # toolchain
  build-essential cmake ninja-build pkg-config git clang-format
  # clang and its sanitizer runtimes (libFuzzer): the clang build and `make fuzz`
  clang libclang-rt-14-dev
  # core libraries
  libyaml-cpp-dev libopencv-dev libeigen3-dev libglm-dev libgeographiclib-dev geographiclib-tools
  libtinygltf-dev libtinyobjloader-dev nlohmann-json3-dev libstb-dev
  # recordings: SQLite (WAL) with zstd-compressed frames; sqlite3 to inspect them
  libsqlite3-dev libzstd-dev zlib1g-dev sqlite3
  # plots of a run's statistics (augrig export)
  gnuplot-nox
  # live capture: Aravis GigE Vision (its pkg-config needs libusb's), V4L2, MJPEG decoding;
  # aravis-tools has the fake GigE Vision camera the tests stream from
  libaravis-dev aravis-tools libusb-1.0-0-dev libv4l-dev libturbojpeg0-dev
  # live nav inputs: gpsd's client library; gpsd and gpsfake for the tests
  libgps-dev gpsd gpsd-clients iproute2
  # the video sink (--sink video:FILE.mp4): H.264 through FFmpeg's libraries (x264); ffprobe
  # reads the files back in the tests
  libavcodec-dev libavformat-dev libavutil-dev libswscale-dev ffmpeg
  # the live display
  libimgui-dev
  # OpenGL: EGL surfaceless (Mesa llvmpipe) and GLFW windows
  libepoxy-dev libegl-dev libgl-dev libegl1 libgl1-mesa-dri libglfw3-dev
  # tests and benches
  libgtest-dev libgmock-dev libbenchmark-dev xvfb xauth
  # the campaign tests' one-node Slurm cluster on loopback (tests/support/local_slurm.hpp); the
  # tests start their own munged, slurmctld and slurmd and need no service running
  slurmctld slurmd slurm-client munge
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
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
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
