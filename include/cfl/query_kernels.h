#pragma once
/// @file
/// Which compiled build of the query's hot code answers the queries of cfl_query.h.
///
/// The search behind computeDistance, computeCollision and bruteForceDistance, with the triangle distance
/// kernels it runs, is compiled twice where the compiler allows it (GCC 12 or later on x86-64, when the
/// library's own flags do not already target AVX2): for the library's flags (baseline x86-64: SSE2) and for
/// x86-64-v3 (AVX2, BMI2, ...), whose three-operand VEX instructions save register copies. The first query
/// picks x86-64-v3 when the CPU runs it. Neither build fuses multiplies into adds (the library is compiled
/// with -ffp-contract=off), so every floating-point operation rounds as written: both return bit for bit the
/// same results, counters included, on every machine; x86-64-v3 runs fewer instructions per query
/// (docs/performance.md has the measurements).
///
/// The environment variable CFL_KERNELS, read once at the first query, overrides the choice: `auto` (the
/// default), `generic` or `x86-64-v3`.

namespace cfl {

/// A compiled build of the query.
enum class QueryKernels {
  kGeneric,   ///< Compiled with the library's flags; always available.
  kX86_64_V3  ///< Compiled for x86-64-v3; needs a CPU with AVX2, BMI2, FMA, F16C, LZCNT and MOVBE.
};

/// The build that runs queries in this process. The first call (or the first query) makes the choice and
/// throws cfl::Error when CFL_KERNELS names an unknown build or one that is not available; later calls return
/// it. Thread-safe.
QueryKernels activeQueryKernels();

/// Whether this library holds `kernels` and this CPU can run them. Thread-safe.
bool queryKernelsAvailable(QueryKernels kernels);

/// Makes `kernels` answer every later query, in every thread: how tests and benchmarks compare the builds.
/// Throws cfl::Error, naming the build, when it is not available. Thread-safe: a query already running
/// finishes in the build it started in.
void setQueryKernels(QueryKernels kernels);

/// The build's name as CFL_KERNELS spells it: "generic" or "x86-64-v3".
const char* queryKernelsName(QueryKernels kernels);

}  // namespace cfl
