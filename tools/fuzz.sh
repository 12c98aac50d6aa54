#!/usr/bin/env bash
# Runs every libFuzzer target of fuzz/ for a fixed time each, starting from seed corpora built from tests/data and
# the bundled scenes/fits. Any crash, sanitizer report, timeout or leak fails the run (exit 1) and leaves the input in
# BUILD/fuzz-artifacts/<target>/; turn it into a regression test (docs/ROBUSTNESS.md, "Fuzzing").
#
#   tools/fuzz.sh [BUILD_DIR] [SECONDS_PER_TARGET] [TARGET...]
#
# BUILD_DIR defaults to build-fuzz, configured and built here if needed (clang, ASan+UBSan, -DBODYFIT_FUZZ=ON).
# FUZZ_RUNS=N stops each target after N executions (SECONDS_PER_TARGET stays the limit): with the fixed -seed the
# run is then the same on every machine, so a CI result can be reproduced here (tools/ci-extra.sh).
# CI (tools/ci-extra.sh) runs a fixed number of executions per target (about 45 s each). The long run documented in docs/ROBUSTNESS.md is
#   tools/fuzz.sh build-fuzz 3600        # one hour per target; the corpora persist in BUILD_DIR/fuzz-corpus/
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build-fuzz}
SECONDS_PER_TARGET=${2:-60}
shift $(( $# >= 2 ? 2 : $# ))
TARGETS=("$@")
if [ ${#TARGETS[@]} -eq 0 ]; then
	TARGETS=(fuzz_ellipsoid_json fuzz_mesh_file fuzz_repair_mesh fuzz_scene fuzz_skin_field)
fi

if [ ! -f "$BUILD/CMakeCache.txt" ]; then
	CC=clang CXX=clang++ cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DBODYFIT_FUZZ=ON \
		-DBODYFIT_SANITIZE=ON -DBODYFIT_BUILD_TESTS=OFF -DBODYFIT_BUILD_DEMOS=ON
fi
cmake --build "$BUILD" --target "${TARGETS[@]}" -j"$(nproc)"

# Seed corpora (regenerated each run; what the fuzzer finds accumulates next to them in the same directory).
seed_dir() { mkdir -p "$BUILD/fuzz-corpus/$1"; echo "$BUILD/fuzz-corpus/$1"; }
S=$(seed_dir fuzz_ellipsoid_json)
cp tests/data/robust_*.json "$S/" 2>/dev/null || true
rm -f "$S/robust_scene_unknown_key.json"
S=$(seed_dir fuzz_scene)
cp demos/scenes/*.json tests/data/robust_scene_unknown_key.json "$S/"
# Nesting at and beyond kMaxJsonDepth (64; input_files.h), and the 100,000-level documents of issue 15 (200 KB:
# hence -max_len 1 MiB below), so the fuzzers start next to the depth check instead of having to grow there.
nested() { head -c "$1" /dev/zero | tr '\0' '['; head -c "$1" /dev/zero | tr '\0' ']'; }
valid_fit='{"format": "bodyfit.ellipsoids", "version": 1, "ellipsoids": [{"region": "head", "center": [0, 1.6, 0], "rotation": [1, 0, 0, 0], "axes": [0.1, 0.12, 0.1]}]'
for n in 63 64 100000; do
	{ printf '%s, "extra": ' "$valid_fit"; nested $n; printf '}'; } >"$(seed_dir fuzz_ellipsoid_json)/seed_nested_$n.json"
	{ printf '{"body": {"mesh": "/etc/passwd", "fit": {"x": '; nested $n; printf '}}, "collider": "none", "garment": {"type": "patch"}}'; } \
		>"$(seed_dir fuzz_scene)/seed_nested_$n.json"
done
# Scenes at the physical ranges of scene.h (issue 15 classes 7 and 9): a looping body motion, the strongest wind.
# The body mesh is a file every Linux system has, so that parsing gets past body.mesh (only existence is checked).
S=$(seed_dir fuzz_scene)
printf '%s' '{"body": {"mesh": "/etc/passwd"}, "collider": "none", "garment": {"type": "tube", "radius_m": 0.005, "length_m": 0.01, "segments": 314},
 "effects": [{"type": "wind", "velocity": [50, -50, 50], "turbulence": 20}, {"type": "aerodynamics", "air_density": 5, "lift": 10, "drag": 10},
 {"type": "body_motion", "loop": true, "keyframes": [{"t": 0}, {"t": 0.5, "translation": [0, 0, 5], "axis": [0, 1, 0], "angle_deg": 360}, {"t": 1}]}]}' \
	>"$S/seed_ranges.json"
S=$(seed_dir fuzz_mesh_file)
# First byte = extension index in fuzz_mesh_file.cpp: 0 .obj, 1 .ply, 3 .glb, 4 .gltf, 9 .bin.
for f in tests/data/*.obj; do { printf '\000'; cat "$f"; } >"$S/seed_$(basename "$f")"; done
for f in tests/data/*.ply; do { printf '\001'; cat "$f"; } >"$S/seed_$(basename "$f")"; done
for f in tests/data/*.glb; do { printf '\003'; cat "$f"; } >"$S/seed_$(basename "$f")"; done
for f in tests/data/*.gltf; do { printf '\004'; cat "$f"; } >"$S/seed_$(basename "$f")"; done
{ printf '\004{"asset": '; nested 100000; printf '}'; } >"$S/seed_nested.gltf"
# OBJ statement counts at the caps of mesh_precheck.cpp (10,000 o/g/usemtl, 1,000 materials), and one over.
{ printf '\000'; cat tests/data/tetra.obj; for i in $(seq 1 10001); do echo "o p$i"; done; } >"$S/seed_many_objects.obj"
{ printf '\000'; cat tests/data/tetra.obj; for i in $(seq 1 1000); do echo "usemtl m$i"; done; } >"$S/seed_many_materials.obj"
# A 20,000-node chain (overflowed assimp's stack; the check refuses it at 256 levels).
{ printf '\004{"asset": {"version": "2.0"}, "nodes": ['; for i in $(seq 1 19999); do printf '{"children": [%d]}, ' "$i"; done
  printf '{}]}'; } >"$S/seed_deep_nodes.gltf"
{ printf '\011'; head -c 256 tests/data/garbage.bin; } >"$S/seed_garbage.bin"
S=$(seed_dir fuzz_repair_mesh)
# 4 vertices, 4 faces, grid mode: a tetrahedron on the 0.1 grid; and the same in raw-double mode (mostly NaN-free).
printf '\003\004\001\000\000\000\001\000\000\000\001\000\000\000\001\000\002\001\000\001\003\000\003\002\001\002\003\000' >"$S/seed_tetra_grid"
head -c 200 tests/data/garbage.bin >"$S/seed_garbage"
# 8 vertices, 8 faces, grid mode: two tetrahedra, at the origin and 0.6 away on each axis (two components, one
# detached: components.h).
printf '\007\010\001\000\000\000\001\000\000\000\001\000\000\000\001\006\006\006\007\006\006\006\007\006\006\006\007\000\002\001\000\001\003\000\003\002\001\002\003\004\006\005\004\005\007\004\007\006\005\006\007\000' >"$S/seed_two_tetra_grid"

# A skin field side file (skin_field.h) baked from a 5 cm cube at a 1 cm voxel, and its header alone.
S=$(seed_dir fuzz_skin_field)
cp tests/data/skin_field_cube.skin "$S/seed_cube.skin"
head -c 104 tests/data/skin_field_cube.skin >"$S/seed_header.skin"

status=0
for t in "${TARGETS[@]}"; do
	exe="$BUILD/fuzz/$t"
	[ -x "$exe" ] || { echo "fuzz: $t not built, skipped"; continue; }
	art="$BUILD/fuzz-artifacts/$t/"
	mkdir -p "$art" "$BUILD/fuzz-logs"
	log="$BUILD/fuzz-logs/$t.log"
	echo "== $t: ${SECONDS_PER_TARGET}s =="
	set +e
	ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
		LSAN_OPTIONS=suppressions="$PWD/fuzz/lsan.supp":print_suppressions=0 "$exe" "$BUILD/fuzz-corpus/$t" -max_total_time="$SECONDS_PER_TARGET" ${FUZZ_RUNS:+-runs="$FUZZ_RUNS"} -seed="${FUZZ_SEED:-1}" -timeout=20 -rss_limit_mb=2048 \
		-max_len=1048576 -artifact_prefix="$art" -print_final_stats=1 >"$log" 2>&1
	rc=$?
	set -e
	runs=$(grep -Eo 'stat::number_of_executed_units: *[0-9]+' "$log" | grep -Eo '[0-9]+$' || echo "?")
	cov=$(grep -Eo 'cov: [0-9]+' "$log" | tail -n 1 || true)
	echo "$t: exit $rc, $runs executions, $cov, corpus $(ls "$BUILD/fuzz-corpus/$t" | wc -l) files"
	if [ $rc -eq 70 ] && [ "$t" = fuzz_mesh_file ]; then
		# libFuzzer timeout (exit 70) inside assimp's importers under ASan: assimp parses some garbled files very
		# slowly (a 2026-11-22 CI run hit one at 26 s). Reported with the input kept, not a CI failure; crashes,
		# sanitizer reports and leaks still fail. See docs/ROBUSTNESS.md section 4.
		echo "$t: WARNING, slow input (timeout) kept in $art"
	elif [ $rc -ne 0 ]; then
		status=1
		echo "$t: FAILED, input(s) in $art"; grep -E "ERROR|SUMMARY|runtime error" "$log" | head -5
	fi
done
exit $status
