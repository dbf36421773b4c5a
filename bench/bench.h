// dejag/bench: benchmarks that print a figure, side by side with the machine's measured peak.
//
// Every case is timed as the median of `repeat` runs after one warm-up run, at each thread count asked
// for, in one process so that ratios between cases are measured under the same machine load.
#pragma once

#include <string>
#include <vector>

namespace dejag::bench {

struct Row {
    std::string name;
    int threads = 1;
    std::string simd;
    double ms = 0.0;            // median wall time of one run
    double gmacs = 0.0;         // multiply-adds per nanosecond (0 if not meaningful)
    double peakGmacs = 0.0;     // measured FMA peak at this thread count
    double peakFraction = 0.0;  // gmacs / peakGmacs
    double targetMs = 0.0;      // the target for this case, 0 if none
};

struct Options {
    int width = 1920, height = 1080;
    int repeat = 15;
    std::vector<int> threads = {1, 2};
};

// PSNR (data range 1) of two float buffers of the same size, for the benchmarks' quick quality columns.
double floatPsnr(const std::vector<float>& a, const std::vector<float>& b);

// SSIM, full metrics (MSE+PSNR+SNR+SSIM) and MSE alone on two RGB float images of the given size.
std::vector<Row> benchMetrics(const Options& options);

}  // namespace dejag::bench
