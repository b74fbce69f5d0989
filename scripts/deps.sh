#!/usr/bin/env bash
# Installs the Debian 12 packages treestereo needs to build, test and run, when missing.
# Uses sudo when not root. Idempotent: does nothing when everything is there.
set -euo pipefail

packages=(
  # build
  meson ninja-build pkg-config g++ python3
  libglib2.0-dev libgstreamer1.0-dev libgstreamer-plugins-base1.0-dev
  libopencv-dev zlib1g-dev
  libaravis-dev libusb-1.0-0-dev
  libgtest-dev
  # run: gst-launch/gst-inspect and the stock elements the pipelines use
  gstreamer1.0-tools gstreamer1.0-plugins-base gstreamer1.0-plugins-base-apps gstreamer1.0-plugins-good
  gstreamer1.0-plugins-bad gstreamer1.0-plugins-ugly gstreamer1.0-libav gstreamer1.0-opencv
  libaravis-0.8-0 aravis-tools
  # tests: memcheck, and the fake camera's loopback address
  valgrind iproute2
  # fuzzing (scripts/fuzz.sh): clang and its libFuzzer + sanitizer runtimes
  clang libclang-rt-14-dev
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "treestereo: installing missing Debian packages: ${missing[*]}" >&2
SUDO=()
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then
    SUDO=(sudo)
  else
    echo "treestereo: not root and no sudo; install these packages first: ${missing[*]}" >&2
    exit 1
  fi
fi
export DEBIAN_FRONTEND=noninteractive
"${SUDO[@]}" apt-get update -q
"${SUDO[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
