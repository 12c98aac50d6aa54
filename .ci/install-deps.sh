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
# The Khronos glTF validator (npm package gltf-validator; third_party_notes/tools.md) checks the .glb that
# bodyfit-drape --frames writes (tests/demos/test_scene_cli.cpp; without it that test checks the file's structure).
if command -v npm >/dev/null 2>&1 && ! (cd / && node -e "require('$(npm root -g)/gltf-validator')" >/dev/null 2>&1); then
	npm install -g --no-audit --no-fund gltf-validator@2.0.0-dev.3.10 >/dev/null 2>&1 || echo "install-deps: gltf-validator not installed (the glTF test falls back to structural checks)"
fi
