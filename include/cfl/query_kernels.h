#pragma once
/// @file
/// Which instruction set's kernels answer the queries of cfl_query.h and point_query.h.
///
/// The searches behind those queries are compiled once, for the library's flags (baseline x86-64: SSE2).
/// Their hot kernels (the triangle distance kernels, the mesh search's list filter and the point query's
/// list scans) also come compiled for x86-64-v3 (AVX2, BMI2, ...) where the compiler allows it (GCC 12 or
/// later on x86-64, when the library's own flags do not already target AVX2); the queries call them through
/// one table per instruction set. The first query picks x86-64-v3 when the CPU runs it. No kernel fuses
/// multiplies into adds (the library is compiled with -ffp-contract=off), so every floating-point operation
/// rounds as written: both sets return bit for bit the same results, counters included, on every machine;
/// the x86-64-v3 set runs fewer instructions per query (docs/performance.md has the measurements).
///
/// The environment variable CFL_KERNELS, read once at the first query, overrides the choice: `auto` (the
/// default), `generic` or `x86-64-v3`.

namespace cfl {

/// A set of the query's kernels.
enum class QueryKernels {
  kGeneric,   ///< Compiled with the library's flags; always available.
  kX86_64_V3  ///< Compiled for x86-64-v3; needs a CPU with AVX2, BMI2, FMA, F16C, LZCNT and MOVBE.
};

/// The kernel set that runs queries in this process. The first call (or the first query) makes the choice and
/// throws cfl::Error when CFL_KERNELS names an unknown set or one that is not available; later calls return
/// it. Thread-safe.
QueryKernels activeQueryKernels();

/// Whether this library holds `kernels` and this CPU can run them. Thread-safe.
bool queryKernelsAvailable(QueryKernels kernels);

/// Makes `kernels` answer every later query, in every thread: how tests and benchmarks compare the sets.
/// Throws cfl::Error, naming the set, when it is not available. Thread-safe: a query already running
/// finishes with the kernels it started with.
void setQueryKernels(QueryKernels kernels);

/// The set's name as CFL_KERNELS spells it: "generic" or "x86-64-v3".
const char* queryKernelsName(QueryKernels kernels);

}  // namespace cfl
