#!/usr/bin/env bash
# Sanitizer runs for CI (called by .ci/run; self-contained, about 10-15 minutes on 2 cores):
#  1. AddressSanitizer + UndefinedBehaviorSanitizer build of the whole test suite in build-asan, then ctest.
#     Built with -DCFL_FILE_BULK_COPY=0 so that the CFL file tests cover the portable byte-by-byte path that
#     big-endian hosts use (the Release build covers the bulk-copy path).
#  2. ThreadSanitizer build of concurrency_test only, in build-tsan, and a run of it.
# To save time both leave out the FCL adapter and the benchmarks (-DCFL_BUILD_FCL_ADAPTER=OFF
# -DCFL_BUILD_BENCH=OFF): the adapter's tests are not sanitized here.
set -euo pipefail
cd "$(dirname "$0")/.."
jobs="${CFL_JOBS:-2}"
start=$(date +%s)
stamp() { echo "=== sanitize [$(( $(date +%s) - start ))s] $*"; }

common=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DCFL_BUILD_FCL_ADAPTER=OFF -DCFL_BUILD_BENCH=OFF)

stamp "ASan+UBSan: configure and build build-asan"
cmake -S . -B build-asan "${common[@]}" -DCFL_SANITIZE=address,undefined -DCMAKE_CXX_FLAGS=-DCFL_FILE_BULK_COPY=0
cmake --build build-asan -j"$jobs"
stamp "ASan+UBSan: ctest"
# halt_on_error and -fno-sanitize-recover make every report a test failure.
export ASAN_OPTIONS="abort_on_error=1:halt_on_error=1:detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
# A leak inside Debian's assimp, not in cfl (see the file).
export LSAN_OPTIONS="suppressions=$PWD/fuzz/lsan_suppressions.txt:print_suppressions=0"
ctest --test-dir build-asan --output-on-failure -j"$jobs"

stamp "TSan: configure and build concurrency_test in build-tsan"
cmake -S . -B build-tsan "${common[@]}" -DCFL_SANITIZE=thread
cmake --build build-tsan --target concurrency_test -j"$jobs"
stamp "TSan: run concurrency_test"
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1"
# Some kernels randomize the address space more than GCC 12's TSan runtime expects ("unexpected memory
# mapping"); running without randomization avoids that and changes nothing else.
run=(./build-tsan/tests/concurrency_test)
if command -v setarch >/dev/null 2>&1 && setarch "$(uname -m)" -R true 2>/dev/null; then
  run=(setarch "$(uname -m)" -R "${run[@]}")
fi
"${run[@]}"
stamp "done"
