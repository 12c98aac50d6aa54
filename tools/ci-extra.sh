#!/usr/bin/env bash
# Extra CI jobs beyond the README's test command:
#   1. the float64 Bullet build (-DBODYFIT_BULLET_DOUBLE=ON): the Bullet-facing tests in double precision;
#   2. an AddressSanitizer + UndefinedBehaviorSanitizer build of the whole test suite (RelWithDebInfo);
#   3. a short libFuzzer run of every fuzz/ target (tools/fuzz.sh, 45 s each; clang).
# Budget on 2 cores: about 35 minutes, mostly compilation.
# Each job uses its own build directory. Any failure fails CI.
set -euo pipefail
cd "$(dirname "$0")/.."
JOBS=$(nproc)

echo "== job: Bullet float64 build =="
cmake -S . -B build-double -DCMAKE_BUILD_TYPE=Release -DBODYFIT_BULLET_DOUBLE=ON -DBODYFIT_BUILD_DEMOS=OFF
cmake --build build-double -j"$JOBS"
ctest --test-dir build-double --output-on-failure -j"$JOBS"


echo "== job: ASan + UBSan build of the whole test suite =="
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DBODYFIT_SANITIZE=ON -DBODYFIT_BUILD_DEMOS=OFF
cmake --build build-asan -j"$JOBS"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
	LSAN_OPTIONS=suppressions="$PWD/fuzz/lsan.supp":print_suppressions=0 ctest --test-dir build-asan --output-on-failure -j"$JOBS"

echo "== job: libFuzzer short run (45 s per target, clang, ASan+UBSan) =="
tools/fuzz.sh build-fuzz 45
