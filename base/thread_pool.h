// dejag/base: the one thread pool of the process.
//
// parallelFor(begin, end, grain, body) splits [begin, end) into chunks of `grain` indices and runs
// body(chunkBegin, chunkEnd) on the pool's workers and the calling thread. Which thread runs which chunk
// varies, so bodies must write disjoint outputs; reductions keep one partial per index and sum them in
// index order afterwards, which makes results independent of the thread count. A parallelFor called from
// inside a body runs serially. The first exception thrown by a body is rethrown to the caller.
// Every worker flushes denormals to zero (FTZ/DAZ), as does setThreadCount()'s caller.
#pragma once

#include <cstdint>

namespace dejag {

// A non-owning reference to a callable body(begin, end): passing a lambda costs no allocation (a
// std::function would allocate for captures beyond two pointers), so a parallelFor per layer per frame
// stays allocation-free. The callable must outlive the call, which parallelFor guarantees by waiting.
class ParallelBody {
  public:
    template <class F>
    ParallelBody(const F& body)  // NOLINT(google-explicit-constructor): lambdas convert implicitly
        : object_(&body), call_([](const void* object, int64_t begin, int64_t end) {
              (*static_cast<const F*>(object))(begin, end);
          }) {}
    void operator()(int64_t begin, int64_t end) const { call_(object_, begin, end); }

  private:
    const void* object_;
    void (*call_)(const void*, int64_t, int64_t);
};

// Number of threads parallelFor uses (workers + caller). Default: DEJAG_THREADS, else the core count.
int threadCount();
// Rebuilds the pool with `threads` threads (>= 1); 0 means the default.
void setThreadCount(int threads);
// grain <= 0 picks about 4 chunks per thread.
void parallelFor(int64_t begin, int64_t end, int64_t grain, const ParallelBody& body);

// Sets FTZ and DAZ on the calling thread so denormals cost nothing (numerical stability: denormals never slow a kernel down).
void flushDenormalsOnThisThread();

int hardwareThreadCount();

}  // namespace dejag
