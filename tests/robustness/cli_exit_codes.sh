#!/usr/bin/env bash
# CLI contract on bad input (docs/DESIGN.md sec. 6, docs/ROBUSTNESS.md): every case exits with the documented code and,
# on failure, prints exactly one line on stderr that names the problem.
# usage: cli_exit_codes.sh BODYFIT_FIT BODYFIT_DRAPE TEST_DATA_DIR   (registered with CTest when the demos are built)
set -u
FIT=$(readlink -f "$1")
DRAPE=$(readlink -f "$2")
DATA=$(readlink -f "$3")
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
fails=0
cases=0

# expect CODE PATTERN -- command...: exit code must be CODE; for CODE != 0, stderr is one line matching PATTERN and
# nothing was written into $W (every refused case points its outputs there).
# With LAST_LINE=1 (bodyfit-drape, which reports progress on stderr), the last stderr line is the error and matches.
# Every command runs under `timeout 20`: a hang (e.g. open() on a FIFO) is a failure (exit 124), not a stuck test.
W="$TMP/w"
LAST_LINE=0
expect() {
	local code=$1 pattern=$2
	shift 3
	cases=$((cases + 1))
	rm -rf "$W"
	mkdir -p "$W"
	timeout 20 "$@" >"$TMP/out" 2>"$TMP/err"
	local got=$?
	if [ "$code" != 0 ] && [ -n "$(ls -A "$W")" ]; then
		echo "FAIL: refused run wrote $(ls -A "$W" | tr '\n' ' '): $*"; fails=$((fails + 1)); return
	fi
	local lines
	lines=$(grep -c '' "$TMP/err")
	if [ "$got" != "$code" ]; then
		echo "FAIL: exit $got (expected $code): $*"; sed 's/^/    stderr: /' "$TMP/err" | head -5; fails=$((fails + 1)); return
	fi
	if [ "$code" != 0 ]; then
		if [ "$LAST_LINE" = 1 ]; then
			tail -n 1 "$TMP/err" >"$TMP/last"
			mv "$TMP/last" "$TMP/err"
			lines=1
		fi
		if [ "$lines" != 1 ] || ! grep -q -- "$pattern" "$TMP/err"; then
			echo "FAIL: stderr is not one line matching '$pattern': $*"; sed 's/^/    stderr: /' "$TMP/err" | head -5
			fails=$((fails + 1)); return
		fi
	fi
	echo "ok   exit $got: $* $( [ "$code" != 0 ] && echo "-> $(cat "$TMP/err")")"
}

if [ -x "$FIT" ]; then
	expect 2 "missing -o" -- "$FIT" "$DATA/tetra.obj"
	expect 2 "robust_does_not_exist.obj: cannot open file" -- "$FIT" "$DATA/robust_does_not_exist.obj" -o "$W/o.json"
	expect 2 "empty.obj: file is empty" -- "$FIT" "$DATA/empty.obj" -o "$W/o.json"
	expect 2 "truncated.obj" -- "$FIT" "$DATA/truncated.obj" -o "$W/o.json"
	expect 2 "robust_truncated.ply" -- "$FIT" "$DATA/robust_truncated.ply" -o "$W/o.json"
	expect 2 "robust_truncated_ascii.ply" -- "$FIT" "$DATA/robust_truncated_ascii.ply" -o "$W/o.json"
	expect 2 "robust_truncated.glb" -- "$FIT" "$DATA/robust_truncated.glb" -o "$W/o.json"
	expect 2 "malformed PLY header" -- "$FIT" "$DATA/robust_fuzz_ply_hang.ply" -o "$W/o.json"
	expect 2 "garbage.bin" -- "$FIT" "$DATA/garbage.bin" -o "$W/o.json"
	expect 2 "non-finite coordinate" -- "$FIT" "$DATA/nan_vertex.obj" -o "$W/o.json"
	expect 2 "non-finite coordinate" -- "$FIT" "$DATA/robust_inf_vertex.obj" -o "$W/o.json"
	expect 2 "fewer than 4 distinct points" -- "$FIT" "$DATA/single_triangle.obj" -o "$W/o.json"
	expect 2 "robust_identical.obj" -- "$FIT" "$DATA/robust_identical.obj" -o "$W/o.json"
	expect 2 "scale" -- "$FIT" "$DATA/tetra.obj" -o "$W/o.json" --scale -1
	expect 2 "up" -- "$FIT" "$DATA/tetra.obj" -o "$W/o.json" --up x
	expect 2 "mu-torso" -- "$FIT" "$DATA/tetra.obj" -o "$W/o.json" --mu-torso nan
	expect 2 "unknown" -- "$FIT" "$DATA/tetra.obj" -o "$W/o.json" --no-such-option
	# Hostile input, round 2 (docs/ROBUSTNESS.md section 7). Non-regular files, also when a mesh names them.
	mkfifo "$TMP/pipe.obj" "$TMP/pipe.mtl"
	expect 2 "pipe.obj: cannot open file: is a FIFO" -- "$FIT" "$TMP/pipe.obj" -o "$W/o.json"
	expect 2 "cannot open file: is a directory" -- "$FIT" "$DATA" -o "$W/o.json"
	expect 2 "cannot open file: is a character device" -- "$FIT" /dev/null -o "$W/o.json"
	{ cat "$DATA/tetra.obj"; echo "mtllib pipe.mtl"; } >"$TMP/mtl_fifo.obj"
	expect 2 "OBJ mtllib names .*pipe.mtl' is a FIFO" -- "$FIT" "$TMP/mtl_fifo.obj" -o "$W/o.json"
	sed 's|data:[^"]*|pipe.mtl|' "$DATA/robust_gltf_buffer_too_long.gltf" >"$TMP/buffer_fifo.gltf"
	expect 2 "buffers\[0\].uri names .*pipe.mtl' is a FIFO" -- "$FIT" "$TMP/buffer_fifo.gltf" -o "$W/o.json"
	# glTF trees, GLB/PLY headers declaring more than the file holds, OBJ statement counts, nested JSON.
	expect 2 "glTF node hierarchy is deeper than 256 levels" -- "$FIT" "$DATA/robust_gltf_deep_nodes.gltf" -o "$W/o.json"
	expect 2 "glTF nodes form a cycle" -- "$FIT" "$DATA/robust_gltf_node_cycle.gltf" -o "$W/o.json"
	expect 2 "byteLength is 4000000000" -- "$FIT" "$DATA/robust_gltf_buffer_too_long.gltf" -o "$W/o.json"
	expect 2 "GLB header declares a JSON chunk of 4026531840 bytes" -- "$FIT" "$DATA/robust_glb_huge_json_chunk.glb" -o "$W/o.json"
	expect 2 "glTF skins\[0\] has no inverseBindMatrices" -- "$FIT" "$DATA/robust_fuzz_glb_skin_no_ibm.glb" -o "$W/o.json"
	expect 2 "robust_gltf_bad_utf8.glb: JSON text (read as glTF) does not parse" -- "$FIT" "$DATA/robust_gltf_bad_utf8.glb" -o "$W/o.json"
	expect 2 "PLY header declares 4000000000 'vertex' elements" -- "$FIT" "$DATA/robust_ply_huge_count.ply" -o "$W/o.json"
	{ cat "$DATA/tetra.obj"; for i in $(seq 10001); do echo "o part$i"; done; } >"$TMP/many_o.obj"
	expect 2 "more than 10000 object/group/material statements" -- "$FIT" "$TMP/many_o.obj" -o "$W/o.json"
	{ printf '{"asset": '; head -c 100000 /dev/zero | tr '\0' '['; } >"$TMP/nested.gltf"
	expect 2 "nested deeper than 64 levels" -- "$FIT" "$TMP/nested.gltf" -o "$W/o.json"
	expect 0 "" -- "$FIT" "$DATA/robust_valid_tetra.glb" -o "$TMP/glb.json"
	# Geometry a fit file cannot hold (class 8): a millimetre mesh fitted without --scale is refused before fitting.
	expect 2 "robust_millimetre.obj: the mesh reaches 1700 m from the origin" -- "$FIT" "$DATA/robust_millimetre.obj" -o "$W/o.json"
	# Outputs (classes 13, 14): checked before the load, never an input, never a forgotten option value.
	echo x >"$TMP/afile"
	cp "$DATA/tetra.obj" "$TMP/in.obj"
	expect 2 "-o: '.*in.obj' is the input mesh; refusing to overwrite it" -- "$FIT" "$TMP/in.obj" -o "$TMP/in.obj"
	cmp -s "$DATA/tetra.obj" "$TMP/in.obj" || { echo "FAIL: the input mesh was changed"; fails=$((fails + 1)); }
	expect 2 "-o needs a value (-o OUT.json), got the option --scale" -- sh -c 'cd "$1" && shift && exec "$@"' sh "$W" "$FIT" "$DATA/tetra.obj" -o --scale 0.01
	expect 2 "-o: cannot write '.*afile/x.json': Not a directory" -- "$FIT" "$DATA/tetra.obj" -o "$TMP/afile/x.json"
	expect 2 "-o: cannot write '/proc/x.json'" -- "$FIT" "$DATA/tetra.obj" -o /proc/x.json
	expect 2 "-o: cannot write '.*': it is a directory" -- "$FIT" "$DATA/tetra.obj" -o "$DATA"
	expect 2 "--segments: '.*a.obj' is also the output of --export-mesh" -- "$FIT" "$DATA/tetra.obj" -o "$W/o.json" --export-mesh "$W/a.obj" --segments "$W/a.obj"
	expect 0 "" -- "$FIT" "$DATA/tetra.obj" -o "$TMP/upper.json" --export-mesh "$TMP/E.OBJ" --segments "$TMP/S.PLY"
	{ [ "$(head -n 1 "$TMP/S.PLY")" = ply ] && grep -q '^v ' "$TMP/E.OBJ"; } || { echo "FAIL: X.PLY / X.OBJ not written in their formats"; fails=$((fails + 1)); }
	# Documented repairs / generic path: these succeed.
	expect 0 "" -- "$FIT" "$DATA/robust_nonmanifold.obj" -o "$TMP/nm.json"
	expect 0 "" -- "$FIT" "$DATA/robust_self_intersecting.obj" -o "$TMP/si.json"
	expect 0 "" -- "$FIT" "$DATA/robust_components.obj" -o "$TMP/rc.json"
	expect 2 "32-bit floats" -- "$FIT" "$DATA/robust_far_origin.obj" -o "$TMP/far.json"
	expect 0 "" -- "$FIT" "$DATA/robust_millimetre.obj" -o "$TMP/mm.json" --scale 0.001
	expect 0 "" -- "$FIT" "$DATA/robust_zup.obj" -o "$TMP/z.json" --up z
	expect 0 "" -- "$FIT" "$DATA/cube_quads.obj" -o "$TMP/cube.json"
	expect 0 "" -- "$FIT" --help
else
	echo "skip: bodyfit-fit not built ($FIT)"
fi

if [ -x "$DRAPE" ]; then
	LAST_LINE=1
	expect 2 "robust_does_not_exist.json" -- "$DRAPE" "$DATA/robust_does_not_exist.json" --steps 1
	expect 2 "colour" -- "$DRAPE" "$DATA/robust_scene_unknown_key.json" --steps 1
	expect 2 "garbage.bin" -- "$DRAPE" "$DATA/garbage.bin" --steps 1
	SCENE="$DATA/../../demos/scenes/windy_patch.json"
	expect 2 "axes" -- "$DRAPE" "$SCENE" --ellipsoids "$DATA/robust_axes_negative.json" --steps 1
	expect 2 "rotation" -- "$DRAPE" "$SCENE" --ellipsoids "$DATA/robust_rotation_nonunit.json" --steps 1
	expect 2 "steps" -- "$DRAPE" "$SCENE" --steps -3
	expect 2 "collider" -- "$DRAPE" "$SCENE" --collider teapot --steps 1
	expect 2 "robust_does_not_exist.obj" -- "$DRAPE" "$SCENE" --body "$DATA/robust_does_not_exist.obj" --steps 1
	# Hostile input, round 2: a directory or FIFO as scene (was an abort / a hang), nested JSON (was a segfault).
	expect 2 "cannot open scene file: is a directory" -- "$DRAPE" "$DATA" --steps 1
	mkfifo "$TMP/pipe.json"
	expect 2 "pipe.json: cannot open scene file: is a FIFO" -- "$DRAPE" "$TMP/pipe.json" --steps 1
	expect 2 "pipe.json: cannot open file: is a FIFO" -- "$DRAPE" "$SCENE" --ellipsoids "$TMP/pipe.json" --steps 1
	sed 's/"axes": \[0.1, 0.12, 0.1\]/"axes": [0.1, 1e39, 0.1]/' "$DATA/robust_valid_one.json" >"$TMP/axes_1e39.json"
	expect 2 "axes\[1\]: must be in \[1e-06, 1000\] m (got 1e+39)" -- "$DRAPE" "$SCENE" --ellipsoids "$TMP/axes_1e39.json" --steps 1
	expect 2 "robust_fit_deep_nesting.json: not a usable JSON document" -- "$DRAPE" "$SCENE" --ellipsoids "$DATA/robust_fit_deep_nesting.json" --steps 1
	{ printf '{"body": {"mesh": "x.obj", "fit": {"x": '; head -c 300000 /dev/zero | tr '\0' '['; } >"$TMP/deep_scene.json"
	expect 2 "deep_scene.json: not a usable JSON document: arrays/objects nested deeper than 64" -- "$DRAPE" "$TMP/deep_scene.json" --steps 1
	# Outputs (class 13): checked before the body is loaded and the run (was exit 1 after the whole simulation).
	sum=$(cksum <"$SCENE")
	expect 2 "--metrics: '.*windy_patch.json' is the scene file; refusing to overwrite it" -- "$DRAPE" "$SCENE" --metrics "$SCENE" --steps 1
	[ "$(cksum <"$SCENE")" = "$sum" ] || { echo "FAIL: the scene was changed"; fails=$((fails + 1)); }
	expect 2 "--metrics: cannot write '/proc/m.json'" -- "$DRAPE" "$SCENE" --metrics /proc/m.json --steps 1
	expect 2 "--metrics: cannot write '.*': it is a directory" -- "$DRAPE" "$SCENE" --metrics "$DATA" --steps 1
	expect 2 "--png: " -- "$DRAPE" "$SCENE" --png "$TMP/afile/p.png" --steps 1
	expect 2 "--png-zoom: '0,1,0' is not X,Y,Z,R .four comma-separated numbers in metres." -- "$DRAPE" "$SCENE" --png "$TMP/p.png" --png-zoom 0,1,0 --steps 1
	expect 2 "--png-zoom: '0,1,nan,0.2' is not X,Y,Z,R .field 3 is not a finite number." -- "$DRAPE" "$SCENE" --png "$TMP/p.png" --png-zoom 0,1,nan,0.2 --steps 1
	expect 2 "--png-zoom: '0,1,0,0' is not X,Y,Z,R .R must be in 0.01..10 m." -- "$DRAPE" "$SCENE" --png "$TMP/p.png" --png-zoom 0,1,0,0 --steps 1
	expect 2 "--png-zoom: needs --png OUT.png" -- "$DRAPE" "$SCENE" --png-zoom 0,1,0,0.2 --steps 1
	expect 2 "--frames: cannot write '.*afile': it exists and is not a directory" -- "$DRAPE" "$SCENE" --frames "$TMP/afile" --steps 1
	BENCH="$(dirname "$FIT")/bodyfit-bench"
	[ -x "$BENCH" ] && expect 2 "--out: cannot write '.*afile': it exists and is not a directory" -- "$BENCH" mvee --out "$TMP/afile"
	# body.fit.max_ellipsoids must be a count (class 14: 0.5 reached the fitter as 0, 1.9 as 1).
	printf '{"body": {"mesh": "%s", "fit": {"max_ellipsoids": 0.5}}, "collider": "ellipsoids", "garment": {"type": "patch"}}' \
		"$DATA/tetra.obj" >"$TMP/half.json"
	expect 2 "body.fit.max_ellipsoids: expected an integer, got a non-integral number 0.5" -- "$DRAPE" "$TMP/half.json" --steps 1
	# Values that produced NaN cloth or launched it (classes 7, 9): refused by physical ranges.
	scene_with() { printf '{"body": {"mesh": "%s"}, "collider": "none", "garment": %s, "effects": %s}' "$DATA/tetra.obj" "$1" "$2"; }
	scene_with '{"type": "patch", "center": [1e6, 0, 0]}' '[]' >"$TMP/far.json"
	expect 2 "garment.center\[0\]: value 1e+06 is outside \[-1000, 1000\]" -- "$DRAPE" "$TMP/far.json" --metrics "$W/m.json" --steps 1
	scene_with '{"type": "tube", "radius_m": 1e-9}' '[]' >"$TMP/thin.json"
	expect 2 "garment.radius_m: value 1e-09 is outside" -- "$DRAPE" "$TMP/thin.json" --metrics "$W/m.json" --steps 1
	scene_with '{"type": "patch"}' '[{"type": "wind", "velocity": [200, 0, 0], "turbulence": 200}, {"type": "aerodynamics", "air_density": 2000}]' >"$TMP/storm.json"
	expect 2 "effects\[0\].velocity\[0\]: value 200 is outside \[-50, 50\]" -- "$DRAPE" "$TMP/storm.json" --metrics "$W/m.json" --steps 1
	scene_with '{"type": "patch"}' '[{"type": "body_motion", "keyframes": [{"t": 0}, {"t": 1e-7, "translation": [0, 0, 0.01]}]}]' >"$TMP/jump.json"
	expect 2 "keyframes\[1\].t: keyframes 1e-07 s apart" -- "$DRAPE" "$TMP/jump.json" --metrics "$W/m.json" --steps 1
	scene_with '{"type": "patch"}' '[{"type": "body_motion", "loop": true, "keyframes": [{"t": 0}, {"t": 1, "translation": [0, 0, 1]}]}]' >"$TMP/loop.json"
	expect 2 "effects\[0\].loop: a looping motion must end where it starts" -- "$DRAPE" "$TMP/loop.json" --metrics "$W/m.json" --steps 1
	expect 0 "" -- "$DRAPE" --help
else
	echo "skip: bodyfit-drape not built ($DRAPE)"
fi

echo "$cases cases, $fails failures"
[ "$fails" = 0 ]
