// dejag/base: wall-clock timing and the median that benchmarks report on a noisy, shared machine.
#pragma once

#include <algorithm>
#include <chrono>
#include <vector>

namespace dejag {

class Stopwatch {
  public:
    Stopwatch() : start_(std::chrono::steady_clock::now()) {}
    double elapsedMs() const {
        return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count();
    }
    void restart() { start_ = std::chrono::steady_clock::now(); }

  private:
    std::chrono::steady_clock::time_point start_;
};

inline double median(std::vector<double> values) {
    if (values.empty()) return 0.0;
    std::sort(values.begin(), values.end());
    size_t n = values.size();
    return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

// Median wall time in milliseconds of `repeat` runs of run(), after one untimed warm-up run (scratch
// buffers, page faults, lazily started threads).
template <class Fn>
double medianMilliseconds(int repeat, Fn&& run) {
    run();
    std::vector<double> times;
    for (int i = 0; i < repeat; ++i) {
        Stopwatch watch;
        run();
        times.push_back(watch.elapsedMs());
    }
    return median(times);
}

}  // namespace dejag
