#!/usr/bin/env bash
# Installs every Debian package bodyfit needs to build, test, render and plot. Idempotent; needs root.
set -euo pipefail
export DEBIAN_FRONTEND=noninteractive
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends \
	build-essential cmake pkg-config git \
	libbullet-dev libeigen3-dev libassimp-dev catch2 nlohmann-json3-dev \
	libosmesa6-dev libpng-dev libbenchmark-dev gnuplot-nox clang libclang-rt-14-dev valgrind >/dev/null
