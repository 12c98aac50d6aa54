#!/usr/bin/env bash
# Runs the five study suites of bodyfit-bench (docs/RESULTS.md) into docs/results/ (CSV + Markdown + PNG plots, the
# gnuplot scripts next to them) and keeps each suite's stdout/stderr log there.
#
#   tools/bench-all.sh [BUILD_DIR] [-- extra bodyfit-bench flags, e.g. --quick or --repeats 3]
#
# BUILD_DIR defaults to build-bench; it is configured in Release and only the bodyfit-bench target is built.
# Needs gnuplot (Debian: gnuplot-nox) for the PNGs; the tables are written without it.
# Budget: under 20 minutes on 2 cores with the defaults (see docs/RESULTS.md for the measured times).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build-bench}
shift || true
[[ "${1:-}" == "--" ]] && shift
EXTRA=("$@")
OUT=docs/results

cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$BUILD" --target bodyfit-bench -j"$(nproc)"
mkdir -p "$OUT"
BENCH="$BUILD/demos/bodyfit-bench"
total_start=$(date +%s)
for suite in accuracy-time paper-table2 body-resolution garment-resolution colliders; do
	start=$(date +%s)
	echo "== $suite ==" >&2
	"$BENCH" "$suite" --out "$OUT" "${EXTRA[@]}" >"$OUT/$suite.log" 2>"$OUT/$suite.err.log"
	echo "   $suite: $(( $(date +%s) - start )) s" >&2
done
echo "all five suites: $(( $(date +%s) - total_start )) s" >&2
