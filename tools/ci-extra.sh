#!/usr/bin/env bash
# Extra CI jobs beyond the README's test command:
#   1. the float64 Bullet build (-DBODYFIT_BULLET_DOUBLE=ON): the Bullet-facing tests in double precision;
#   2. an AddressSanitizer + UndefinedBehaviorSanitizer build of the whole test suite (RelWithDebInfo);
#   3. a ThreadSanitizer build of the fitting and scene-runner tests, running those tagged [threads]: fits, bakes and
#      simulations in threads of their own at the same time, and each library's own threads;
#   4. a short libFuzzer run of every fuzz/ target (tools/fuzz.sh, a fixed number of executions, ~45 s each; clang).
# Budget on 2 cores: about 42 minutes, mostly compilation.
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

echo "== job: ThreadSanitizer: the [threads] tests (fits, bakes and simulations in threads at the same time) =="
# Only the two suites that hold [threads] tests, built with -fsanitize=thread (about 6 minutes on 2 cores); Bullet and
# assimp are not instrumented, so what this sees is bodyfit's own memory. tools/tsan.supp says what it drops and why.
cmake -S . -B build-tsan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DBODYFIT_BUILD_DEMOS=OFF \
	-DCMAKE_CXX_FLAGS=-fsanitize=thread -DCMAKE_EXE_LINKER_FLAGS=-fsanitize=thread
cmake --build build-tsan -j"$JOBS" --target tests_fitting tests_drape
for suite in tests_fitting tests_drape; do
	TSAN_OPTIONS=suppressions="$PWD/tools/tsan.supp":halt_on_error=1 "build-tsan/tests/$suite" "[threads]"
done

echo "== job: libFuzzer short run (a fixed number of executions per target, about 45 s each; clang, ASan+UBSan) =="
# Counts, not time: with the fixed seed the same inputs run on every machine, so what passed here passes in CI and
# a finding reproduces. About 45 s per target on 2 cores (CI, 2026-12-01); 240 s is the limit on a slow machine (fuzz_mesh_file took 119 s here beside a build).
declare -A FUZZ_RUN_COUNTS=([fuzz_ellipsoid_json]=500000 [fuzz_mesh_file]=1500 [fuzz_repair_mesh]=250000
	[fuzz_scene]=500000 [fuzz_skin_field]=1500000)
fuzz_status=0
for t in fuzz_ellipsoid_json fuzz_mesh_file fuzz_repair_mesh fuzz_scene fuzz_skin_field; do
	FUZZ_RUNS=${FUZZ_RUN_COUNTS[$t]} tools/fuzz.sh build-fuzz 240 "$t" || fuzz_status=1
done
exit $fuzz_status
