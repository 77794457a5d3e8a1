#!/usr/bin/env bash
# Builds everything and runs the whole test suite with CTest.
set -euo pipefail
cd "$(dirname "$0")/.."
# The tests also need a browser: the report test loads every bundled recipe's report in
# headless Chromium (tests/cli/report_browser_test.cc), and fails rather than skips without it.
./scripts/install_deps.sh --tests
./scripts/build.sh
(cd build && RODFIT_BROWSER_REQUIRED=1 ctest --output-on-failure -j"$(nproc)")

# Issue 15: the fuzz corpus (tests/cli/fuzz_corpus_test.cc) once more on an address +
# undefined-behaviour sanitizer build of the CLI and its libraries (no benchmarks), in
# build-sanitize/. A memory error or undefined behaviour aborts rodfit, which the corpus counts as
# a crash and fails on.
# Issue 34: the C API corpus too (tests/runtime/c_api_corpus_test.cc), with the C API, export,
# profile-reader, time-budget and no-allocation tests of the same program — the ones the sanitizers
# found defects in (under a minute under the sanitizers; the tool-path torture and the long closed-path
# tests, ~30 min there, stay in the ordinary suite). Only test_runtime is built of the tests: it
# needs the runtime, solve and model layers the CLI's build already made. Its tests are not
# discovered at build time (PRE_TEST): nothing runs CTest in this tree.
cmake -S . -B build-sanitize -DCMAKE_BUILD_TYPE=Release -DRODFIT_SANITIZE=ON \
  -DRODFIT_BUILD_TESTS=ON -DCMAKE_GTEST_DISCOVER_TESTS_DISCOVERY_MODE=PRE_TEST \
  -DRODFIT_BUILD_BENCH=OFF >/dev/null
cmake --build build-sanitize --target rodfit-cli test_runtime -j"$(nproc)"
export ASAN_OPTIONS=detect_leaks=0:abort_on_error=1
export UBSAN_OPTIONS=halt_on_error=1:abort_on_error=1:print_stacktrace=1
RODFIT_FUZZ_CLI="$PWD/build-sanitize/rodfit" RODFIT_FUZZ_TIMEOUT=120 \
  build/test_cli --gtest_filter='FuzzCorpusTest.*'
build-sanitize/test_runtime \
  --gtest_filter='CApi*.*:Export*.*:SofaExport.*:MujocoExport.*:RestShapeExport.*:ProfileReader.*:Runtime.*TimeBudget*:Ticks/NoAllocation.*'
