#!/usr/bin/env bash
# Installs the Debian 12 packages LookUP builds and runs with. Idempotent: packages that are
# already installed are skipped, so a second run does no network access at all.
set -euo pipefail

packages=(
    build-essential cmake ninja-build pkg-config
    dpkg-dev file
    libmrpt-dev mrpt-apps
    libopencv-dev libceres-dev libeigen3-dev
    libtorch-dev
    libgtest-dev libgmock-dev libbenchmark-dev
    nlohmann-json3-dev gnuplot-nox
)

missing=()
for p in "${packages[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
        missing+=("$p")
    fi
done

if [ ${#missing[@]} -eq 0 ]; then
    echo "install-deps: all ${#packages[@]} packages present"
    exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}"
