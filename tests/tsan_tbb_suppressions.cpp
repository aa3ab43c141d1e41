// ThreadSanitizer suppressions for concurrency_test's batch tests, compiled only in TSan builds.
//
// The batch API runs on oneTBB, and Debian's libtbb.so is not instrumented: TSan does not see the
// synchronization inside it (task spawning, stealing, the small-object pool that hands one thread's freed task
// memory to another), so it reports races on TBB's task objects between TBB's own header code on different
// threads. src/batch_query.cpp annotates the order between the caller and the chunks for TSan, which removes
// every report on cfl's own data; what is left is inside TBB's tasks. TSan matches a suppression against
// every frame of a report, and every access made inside a TBB task has TBB frames below it, so these patterns
// also stop TSan from checking the queries that the batch runs. Those queries are checked where no TBB is
// involved: ThreadsQueryingSharedModelsAgreeWithSerialAnswers runs them on shared models from plain
// std::threads, which is where a race in the query code would show. The batch's own guarantee, answers
// bit-identical to the serial ones for every thread count and chunk size, is checked by the tests themselves.
#if defined(__SANITIZE_THREAD__)
#define CFL_TSAN_SUPPRESSIONS 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define CFL_TSAN_SUPPRESSIONS 1
#endif
#endif

#ifdef CFL_TSAN_SUPPRESSIONS
extern "C" const char* __tsan_default_suppressions() {
  return "race:tbb::detail::\n"
         "race:libtbb.so\n";
}
#endif
