#include "base/peak.h"

#include <algorithm>
#include <atomic>
#include <vector>

#include "base/thread_pool.h"
#include "base/timer.h"

namespace dejag {

DEJAG_SIMD_DECLARE(uint64_t fmaBurn(int64_t iterations, float* sink);)

FmaPeak measureFmaPeak(double milliseconds) {
    FmaPeak peak;
    peak.threads = threadCount();
    peak.level = activeSimdLevel();
    float sink = 0.0f;
    // Calibrate the iteration count on one thread to ~5 ms.
    int64_t iterations = 1 << 16;
    for (;;) {
        Stopwatch watch;
        DEJAG_SIMD_CALL(fmaBurn, iterations, &sink);
        if (watch.elapsedMs() > 5.0 || iterations > (int64_t(1) << 34)) break;
        iterations *= 2;
    }
    const int bursts = std::max(3, int(milliseconds / 10.0));
    std::vector<double> rates;
    for (int burst = 0; burst < bursts; ++burst) {
        std::atomic<uint64_t> macs{0};
        Stopwatch watch;
        parallelFor(0, peak.threads, 1, [&](int64_t, int64_t) {
            float localSink = 0.0f;
            macs += DEJAG_SIMD_CALL(fmaBurn, iterations, &localSink);
        });
        rates.push_back(double(macs.load()) / (watch.elapsedMs() * 1e6));
    }
    peak.gmacsTotal = median(rates);
    peak.gmacsPerThread = peak.gmacsTotal / peak.threads;
    return peak;
}

}  // namespace dejag
