#include "bench/collective_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "base/communicator.h"
#include "base/error.h"

namespace dejag::bench {
namespace {

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v[v.size() / 2];
}

// Least squares t = a + b x in relative error (weights 1 / t^2), so that the small sizes, where the
// latency shows, count as much as the large ones.
std::pair<double, double> fitLine(const std::vector<double>& x, const std::vector<double>& t) {
    double sw = 0, sx = 0, st = 0, sxx = 0, sxt = 0;
    for (size_t i = 0; i < x.size(); ++i) {
        const double w = 1.0 / std::max(t[i] * t[i], 1e-30);
        sw += w, sx += w * x[i], st += w * t[i], sxx += w * x[i] * x[i], sxt += w * x[i] * t[i];
    }
    const double b = (sw * sxt - sx * st) / (sw * sxx - sx * sx);
    return {(st - b * sx) / sw, b};
}

}  // namespace

nlohmann::json benchCollective(const CollectiveBenchOptions& options) {
    Communicator& comm = communicator();
    const int N = comm.size();
    if (options.repeat < 1) throw Error("--repeat must be at least 1");
    nlohmann::json sizes = nlohmann::json::array();
    // The cost of each, for P floats a rank (latency alpha a step, beta a byte). The ordered sum: an
    // all-to-all (N - 1 pairwise steps) that brings each rank its slice of every vector, (N - 1) / N 4P
    // bytes, then a gather of the slices (log2 N steps, as many bytes). An all-reduce as MPI libraries do
    // it for gradients of this size, a reduce-scatter and a gather (Rabenseifner): 2 log2 N steps,
    // 2 (N - 1) / N 4P bytes. Fitted as t / steps = alpha + beta bytes / steps.
    const auto log2n = [](int n) { return std::ceil(std::log2(double(n))); };
    const auto orderedSteps = [&](int n) { return (n - 1) + log2n(n); };
    const auto reduceSteps = [&](int n) { return 2 * log2n(n); };
    const auto bytes = [](int n, double floats) { return 2.0 * (n - 1) / n * 4.0 * floats; };
    std::vector<double> orderedX, orderedT, reduceX, reduceT;
    std::vector<float> scratch;
    for (int64_t count : options.floats) {
        const size_t n = static_cast<size_t>(count);
        std::vector<float> mine(n, 1.0f), sum(n), reduced(n);
        std::vector<double> ordered, reduce;
        for (int r = 0; r < options.repeat + 3; ++r) {
            comm.barrier();
            auto start = std::chrono::steady_clock::now();
            sumInOrder(mine.data(), 1, N, count, sum.data(), scratch);
            const double o = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            std::copy(mine.begin(), mine.end(), reduced.begin());
            comm.barrier();
            start = std::chrono::steady_clock::now();
            comm.allReduceSum(reduced.data(), count);
            const double a = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            if (r >= 3) ordered.push_back(o), reduce.push_back(a);
        }
        // Every rank's medians, and the slowest rank's (the step waits for it).
        double mineMedians[2] = {median(ordered), median(reduce)};
        std::vector<double> everyone(size_t(2 * N));
        comm.allGather(mineMedians, 2, everyone.data());
        double o = 0, a = 0;
        for (int r = 0; r < N; ++r)
            o = std::max(o, everyone[size_t(2 * r)]), a = std::max(a, everyone[size_t(2 * r + 1)]);
        sizes.push_back({{"floats", count}, {"ordered_ms", o * 1e3}, {"allreduce_ms", a * 1e3}});
        if (N > 1) {
            orderedX.push_back(bytes(N, double(count)) / orderedSteps(N)),
                orderedT.push_back(o / orderedSteps(N));
            reduceX.push_back(bytes(N, double(count)) / reduceSteps(N)),
                reduceT.push_back(a / reduceSteps(N));
        }
    }
    nlohmann::json result = {{"ranks", N}, {"sizes", sizes}};
    if (N < 2 || options.floats.size() < 2) return result;
    auto [orderedLatency, orderedPerByte] = fitLine(orderedX, orderedT);
    auto [reduceLatency, reducePerByte] = fitLine(reduceX, reduceT);
    result["fit"] = {
        {"ordered", {{"latency_us", orderedLatency * 1e6}, {"gb_per_s", 1e-9 / orderedPerByte}}},
        {"allreduce", {{"latency_us", reduceLatency * 1e6}, {"gb_per_s", 1e-9 / reducePerByte}}}};
    if (options.parameters <= 0 || options.stepSeconds <= 0) return result;
    if (options.networkLatencyUs > 0 && options.networkGbPerS > 0) {  // a cluster's network instead
        orderedLatency = reduceLatency = options.networkLatencyUs * 1e-6;
        orderedPerByte = reducePerByte = 1e-9 / options.networkGbPerS;
        result["network"] = {{"latency_us", options.networkLatencyUs}, {"gb_per_s", options.networkGbPerS}};
    }
    nlohmann::json model = nlohmann::json::array();
    const double P = double(options.parameters);
    for (int n : options.ranks) {
        const double ordered = orderedSteps(n) * std::max(0.0, orderedLatency) + bytes(n, P) * orderedPerByte;
        const double reduce = reduceSteps(n) * std::max(0.0, reduceLatency) + bytes(n, P) * reducePerByte;
        const double compute = options.stepSeconds / n;
        model.push_back({{"ranks", n},
                         {"compute_ms", compute * 1e3},
                         {"ordered_ms", ordered * 1e3},
                         {"allreduce_ms", reduce * 1e3},
                         {"efficiency_ordered", compute / (compute + ordered)},
                         {"efficiency_allreduce", compute / (compute + reduce)}});
    }
    result["model"] = model;
    result["parameters"] = options.parameters;
    result["step_seconds"] = options.stepSeconds;
    return result;
}

}  // namespace dejag::bench
