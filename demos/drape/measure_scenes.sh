#!/usr/bin/env bash
# Runs every bundled scene with the ellipsoid collider (full length, and the first BVH_STEPS steps for a like-for-like
# cost comparison), with Bullet's mesh collider (mesh-bvh) and with the convex-hull compound (first BVH_STEPS steps
# only: mesh-bvh costs seconds per step), and writes metrics JSON + pictures to OUT (default out/drape).
# Usage: demos/drape/measure_scenes.sh [BUILD_DIR] [OUT] [BVH_STEPS]
set -euo pipefail
cd "$(dirname "$0")/../.."
BUILD=${1:-build}
OUT=${2:-out/drape}
BVH_STEPS=${3:-8}
mkdir -p "$OUT"
for scene in demos/scenes/*.json; do
	name=$(basename "$scene" .json)
	"$BUILD/demos/bodyfit-drape" "$scene" --collider ellipsoids --metrics "$OUT/$name.ellipsoids.json" \
		--png "$OUT/$name.ellipsoids.png"
	"$BUILD/demos/bodyfit-drape" "$scene" --collider ellipsoids --metrics "$OUT/$name.ellipsoids.short.json" \
		--steps "$BVH_STEPS" >/dev/null
	"$BUILD/demos/bodyfit-drape" "$scene" --collider mesh-bvh --steps "$BVH_STEPS" \
		--metrics "$OUT/$name.mesh-bvh.short.json" --png "$OUT/$name.mesh-bvh.short.png"
	"$BUILD/demos/bodyfit-drape" "$scene" --collider convex-hull-compound --steps "$BVH_STEPS" \
		--metrics "$OUT/$name.convex-hull-compound.short.json" >/dev/null
done
