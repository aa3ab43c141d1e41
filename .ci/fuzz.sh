#!/usr/bin/env bash
# Fuzzing for CI (called by .ci/run; self-contained, about 5 minutes on 2 cores): builds the libFuzzer
# targets of fuzz/ with clang under AddressSanitizer + UndefinedBehaviorSanitizer in build-fuzz, replays
# every saved regression input, then fuzzes each target for FUZZ_SECONDS (default 60) starting from its
# seed corpus in fuzz/corpus/<target>/. Exits non-zero on any crash, sanitizer report, leak, timeout or
# out-of-memory; the failing input is left in build-fuzz/artifacts/<target>/ and its path printed.
# New inputs found go to build-fuzz/corpus-run/ and never into the source tree.
set -euo pipefail
cd "$(dirname "$0")/.."
root="$PWD"
jobs="${CFL_JOBS:-2}"
seconds="${FUZZ_SECONDS:-60}"
start=$(date +%s)
stamp() { echo "=== fuzz [$(( $(date +%s) - start ))s] $*"; }

stamp "configure and build build-fuzz (clang, fuzzer-no-link,address,undefined)"
cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  -DCFL_BUILD_FUZZERS=ON -DCFL_BUILD_TESTS=OFF -DCFL_BUILD_BENCH=OFF -DCFL_BUILD_FCL_ADAPTER=OFF \
  -DCFL_SANITIZE=fuzzer-no-link,address,undefined
targets=(cfl_file_fuzzer)
if grep -q '^mesh_obj_fuzzer:' <(cmake --build build-fuzz --target help 2>/dev/null | sed 's/^\.\.\. //; s/ .*//; s/$/:/'); then
  targets+=(mesh_obj_fuzzer)
fi
cmake --build build-fuzz --target "${targets[@]}" -j"$jobs"

export ASAN_OPTIONS="abort_on_error=1:detect_leaks=1"
export LSAN_OPTIONS="suppressions=$root/fuzz/lsan_suppressions.txt:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
status=0
for target in "${targets[@]}"; do
  binary="$root/build-fuzz/fuzz/$target"
  artifacts="$root/build-fuzz/artifacts/$target"
  work="$root/build-fuzz/corpus-run/$target"
  mkdir -p "$artifacts" "$work"
  options=(-rss_limit_mb=2048 -malloc_limit_mb=1024 -timeout=20 -max_len=16384 -print_final_stats=1
           "-artifact_prefix=$artifacts/")
  regressions="$root/fuzz/regressions/$target"
  if [ -d "$regressions" ] && [ -n "$(ls -A "$regressions")" ]; then
    stamp "$target: replaying $(ls "$regressions" | wc -l) regression inputs"
    if ! "$binary" "${options[@]}" "$regressions"/*; then
      echo "FUZZ FAILURE: $target crashed on a saved regression input"
      status=1
      continue
    fi
  fi
  stamp "$target: fuzzing for ${seconds}s"
  if "$binary" "${options[@]}" -max_total_time="$seconds" "$work" "$root/fuzz/corpus/$target" >"$artifacts/log.txt" 2>&1; then
    grep -E '^stat::(number_of_executed_units|average_exec_per_sec|new_units_added)' "$artifacts/log.txt" || true
  else
    tail -n 60 "$artifacts/log.txt"
    echo "FUZZ FAILURE: $target; reproducer: $(ls -t "$artifacts"/crash-* "$artifacts"/leak-* "$artifacts"/timeout-* "$artifacts"/oom-* 2>/dev/null | head -n 1)"
    status=1
  fi
done
stamp "done"
exit "$status"
