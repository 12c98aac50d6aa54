#!/usr/bin/env bash
# Runs every static bundled scene (full length) with the ellipsoid collider on both surfaces, tight (the skin field,
# the default) and ellipsoids (the paper's response), and prints one row per scene and surface from the metrics JSON:
# nodes inside the body (end / worst sample), mean and p95 contact gap (nodes within skin offset + 3 mm of the union
# or inside it, to the real skin), collision ms per step.
# Usage: tools/compare_surfaces.sh [BUILD_DIR] [OUT]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build}
OUT=${2:-out/surfaces}
mkdir -p "$OUT"
for scene in demos/scenes/*.json; do
	name=$(basename "$scene" .json)
	case "$name" in animated_*) continue ;; esac # an animated body has no skin field (its skin moves)
	for surface in tight ellipsoids; do
		"$BUILD/demos/bodyfit-drape" "$scene" --surface "$surface" --metrics "$OUT/$name.$surface.json" >/dev/null
	done
done
python3 - "$OUT" <<'PY'
import json, pathlib, sys
out = pathlib.Path(sys.argv[1])
print("| scene | surface | inside end / worst | mean contact gap mm | p95 mm | collision ms/step |")
print("|---|---|---|---|---|---|")
for f in sorted(out.glob("*.json")):
    name, surface = f.stem.rsplit(".", 1)
    m = json.loads(f.read_text())
    mm = lambda k: "%.1f" % (1e3 * m[k]) if m.get(k) is not None else "-"
    print("| %s | %s | %d / %d | %s | %s | %.3f |" % (name, surface, m["nodes_inside_body"], m["max_nodes_inside_body"],
          mm("mean_contact_gap_m"), mm("p95_contact_gap_m"), m["collision_ms_per_step"]))
PY
