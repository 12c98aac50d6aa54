#!/usr/bin/env bash
# Collider cost on a moving body against the same garment on the same body at rest (issue 13's goal: within 1.5x).
# For every bundled animated scene: the scene as it is (the skinned body follows its clip), and the same scene with
# the rig's bind pose as a static body (body.mesh = the rig, fitted at load) for the same number of steps. Prints per
# scene and surface the median over REPEATS runs (default 3, interleaved) of the collider's thread CPU per cloth node
# and step (collider_cpu_ns_per_node_step_median of the metrics JSON), moving / static, and the nodes inside the body.
# The static tight runs leave the edge lift off (--no-lift-edges): a body whose ellipsoids sweep never runs it, so
# the ratio measures what motion costs, not that extra phase.
# Usage: [REPEATS=3] [STEPS=200] tools/moving_cost.sh [BUILD_DIR] [OUT]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build}
OUT=${2:-out/moving_cost}
REPEATS=${REPEATS:-3}
STEPS=${STEPS:-200}
mkdir -p "$OUT"
: >"$OUT/runs.log" # the runs' progress and warnings
for scene in demos/scenes/animated_*.json; do
	name=$(basename "$scene" .json)
	python3 - "$scene" "$PWD/demos/scenes" "$OUT/$name.static.json" <<'PY'
import json, os, sys
scene, scenes, out = sys.argv[1:]
s = json.load(open(scene))
rig = os.path.normpath(os.path.join(scenes, s["body"]["animation"]["file"]))
s["name"] = s["name"] + "@bind_pose"
s["body"] = {"mesh": rig, "fit": {}}
if "mesh" in s["garment"]:
    s["garment"]["mesh"] = os.path.normpath(os.path.join(scenes, s["garment"]["mesh"]))
json.dump(s, open(out, "w"), indent=1)
PY
	for r in $(seq "$REPEATS"); do
		for surface in ellipsoids tight; do
			"$BUILD/demos/bodyfit-drape" "$scene" --surface "$surface" --steps "$STEPS" \
				--metrics "$OUT/$name.moving.$surface.$r.json" >/dev/null 2>>"$OUT/runs.log"
			nolift=()
			[ "$surface" = tight ] && nolift=(--no-lift-edges)
			"$BUILD/demos/bodyfit-drape" "$OUT/$name.static.json" --surface "$surface" "${nolift[@]}" --steps "$STEPS" \
				--metrics "$OUT/$name.static.$surface.$r.json" >/dev/null 2>>"$OUT/runs.log"
		done
	done
done
python3 - "$OUT" "$REPEATS" <<'PY'
import glob, json, os, statistics, sys
out, repeats = sys.argv[1], int(sys.argv[2])
def runs(pattern):
    return [json.load(open(f)) for f in sorted(glob.glob(os.path.join(out, pattern)))]
print("| scene | surface | moving ns/node/step | static ns/node/step | moving / static | inside (moving, worst) | inside (static, worst) |")
print("|---|---|---|---|---|---|---|")
names = sorted({os.path.basename(f).split(".")[0] for f in glob.glob(os.path.join(out, "*.moving.*.json"))})
for name in names:
    for surface in ("ellipsoids", "tight"):
        m = runs("%s.moving.%s.*.json" % (name, surface))
        s = runs("%s.static.%s.*.json" % (name, surface))
        if not m or not s:
            continue
        mm = statistics.median(r["collider_cpu_ns_per_node_step_median"] for r in m)
        sm = statistics.median(r["collider_cpu_ns_per_node_step_median"] for r in s)
        print("| %s | %s | %.0f | %.0f | %.2fx | %d | %d |" % (name, surface, mm, sm, mm / sm,
              max(r["max_nodes_inside_body"] for r in m), max(r["max_nodes_inside_body"] for r in s)))
PY
