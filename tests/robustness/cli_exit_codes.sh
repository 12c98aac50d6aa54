#!/usr/bin/env bash
# CLI contract on bad input (docs/DESIGN.md sec. 6, docs/ROBUSTNESS.md): every case exits with the documented code and,
# on failure, prints exactly one line on stderr that names the problem.
# usage: cli_exit_codes.sh BODYFIT_FIT BODYFIT_DRAPE TEST_DATA_DIR   (registered with CTest when the demos are built)
set -u
FIT=$1
DRAPE=$2
DATA=$3
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
fails=0
cases=0

# expect CODE PATTERN -- command...: exit code must be CODE; for CODE != 0, stderr is one line matching PATTERN.
# With LAST_LINE=1 (bodyfit-drape, which reports progress on stderr), the last stderr line is the error and matches.
LAST_LINE=0
expect() {
	local code=$1 pattern=$2
	shift 3
	cases=$((cases + 1))
	"$@" >"$TMP/out" 2>"$TMP/err"
	local got=$?
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
	expect 2 "robust_does_not_exist.obj: cannot open file" -- "$FIT" "$DATA/robust_does_not_exist.obj" -o "$TMP/o.json"
	expect 2 "empty.obj: file is empty" -- "$FIT" "$DATA/empty.obj" -o "$TMP/o.json"
	expect 2 "truncated.obj" -- "$FIT" "$DATA/truncated.obj" -o "$TMP/o.json"
	expect 2 "robust_truncated.ply" -- "$FIT" "$DATA/robust_truncated.ply" -o "$TMP/o.json"
	expect 2 "robust_truncated_ascii.ply" -- "$FIT" "$DATA/robust_truncated_ascii.ply" -o "$TMP/o.json"
	expect 2 "robust_truncated.glb" -- "$FIT" "$DATA/robust_truncated.glb" -o "$TMP/o.json"
	expect 2 "malformed PLY header" -- timeout 60 "$FIT" "$DATA/robust_fuzz_ply_hang.ply" -o "$TMP/o.json"
	expect 2 "garbage.bin" -- "$FIT" "$DATA/garbage.bin" -o "$TMP/o.json"
	expect 2 "non-finite coordinate" -- "$FIT" "$DATA/nan_vertex.obj" -o "$TMP/o.json"
	expect 2 "non-finite coordinate" -- "$FIT" "$DATA/robust_inf_vertex.obj" -o "$TMP/o.json"
	expect 2 "fewer than 4 distinct points" -- "$FIT" "$DATA/single_triangle.obj" -o "$TMP/o.json"
	expect 2 "robust_identical.obj" -- "$FIT" "$DATA/robust_identical.obj" -o "$TMP/o.json"
	expect 2 "scale" -- "$FIT" "$DATA/tetra.obj" -o "$TMP/o.json" --scale -1
	expect 2 "up" -- "$FIT" "$DATA/tetra.obj" -o "$TMP/o.json" --up x
	expect 2 "mu-torso" -- "$FIT" "$DATA/tetra.obj" -o "$TMP/o.json" --mu-torso nan
	expect 2 "unknown" -- "$FIT" "$DATA/tetra.obj" -o "$TMP/o.json" --no-such-option
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
	expect 0 "" -- "$DRAPE" --help
else
	echo "skip: bodyfit-drape not built ($DRAPE)"
fi

echo "$cases cases, $fails failures"
[ "$fails" = 0 ]
