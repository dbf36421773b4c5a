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
    // The cost of the algorithms MPI libraries use for gradients of this size, for P floats a rank
    // (latency alpha a step, beta a byte): a gather, log2 N steps (recursive doubling or Bruck) that
    // together bring in the other ranks' (N - 1) 4P bytes; an all-reduce, a reduce-scatter and a gather
    // (Rabenseifner), 2 log2 N steps moving 2 (N - 1) / N 4P bytes. Fitted as t / steps = alpha + beta
    // bytes / steps.
    const auto steps = [](int n) { return std::ceil(std::log2(double(n))); };
    const auto gatherCost = [&](int n, double floats, double alpha, double beta) {
        return steps(n) * alpha + (n - 1) * 4.0 * floats * beta;
    };
    const auto reduceCost = [&](int n, double floats, double alpha, double beta) {
        return 2 * steps(n) * alpha + 2.0 * (n - 1) / n * 4.0 * floats * beta;
    };
    std::vector<double> gatherBytes, gatherSeconds, reduceBytes, reduceSeconds;
    for (int64_t count : options.floats) {
        std::vector<float> mine(size_t(count), 1.0f), all(size_t(count) * size_t(N));
        std::vector<float> sum(static_cast<size_t>(count));
        std::vector<double> gather, reduce;
        for (int r = 0; r < options.repeat + 3; ++r) {
            comm.barrier();
            auto start = std::chrono::steady_clock::now();
            comm.allGather(mine.data(), count, all.data());
            const double g = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            std::copy(mine.begin(), mine.end(), sum.begin());
            comm.barrier();
            start = std::chrono::steady_clock::now();
            comm.allReduceSum(sum.data(), count);
            const double a = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            if (r >= 3) gather.push_back(g), reduce.push_back(a);
        }
        // Every rank's medians, and the slowest rank's (the step waits for it).
        double mineMedians[2] = {median(gather), median(reduce)};
        std::vector<double> everyone(size_t(2 * N));
        comm.allGather(mineMedians, 2, everyone.data());
        double g = 0, a = 0;
        for (int r = 0; r < N; ++r)
            g = std::max(g, everyone[size_t(2 * r)]), a = std::max(a, everyone[size_t(2 * r + 1)]);
        sizes.push_back({{"floats", count}, {"gather_ms", g * 1e3}, {"allreduce_ms", a * 1e3}});
        if (N > 1) {
            gatherBytes.push_back((N - 1) * 4.0 * double(count) / steps(N)),
                gatherSeconds.push_back(g / steps(N));
            reduceBytes.push_back(2.0 * (N - 1) / N * 4.0 * double(count) / (2 * steps(N)));
            reduceSeconds.push_back(a / (2 * steps(N)));
        }
    }
    nlohmann::json result = {{"ranks", N}, {"sizes", sizes}};
    if (N < 2 || options.floats.size() < 2) return result;
    auto [gatherLatency, gatherPerByte] = fitLine(gatherBytes, gatherSeconds);
    auto [reduceLatency, reducePerByte] = fitLine(reduceBytes, reduceSeconds);
    result["fit"] = {
        {"gather", {{"latency_us", gatherLatency * 1e6}, {"gb_per_s", 1e-9 / gatherPerByte}}},
        {"allreduce", {{"latency_us", reduceLatency * 1e6}, {"gb_per_s", 1e-9 / reducePerByte}}}};
    if (options.parameters <= 0 || options.stepSeconds <= 0) return result;
    if (options.networkLatencyUs > 0 && options.networkGbPerS > 0) {  // a cluster's network instead
        gatherLatency = reduceLatency = options.networkLatencyUs * 1e-6;
        gatherPerByte = reducePerByte = 1e-9 / options.networkGbPerS;
        result["network"] = {{"latency_us", options.networkLatencyUs}, {"gb_per_s", options.networkGbPerS}};
    }
    nlohmann::json model = nlohmann::json::array();
    const double P = double(options.parameters);
    for (int n : options.ranks) {
        const double gather = gatherCost(n, P, std::max(0.0, gatherLatency), gatherPerByte);
        const double reduce = reduceCost(n, P, std::max(0.0, reduceLatency), reducePerByte);
        const double compute = options.stepSeconds / n;
        model.push_back({{"ranks", n},
                         {"compute_ms", compute * 1e3},
                         {"gather_ms", gather * 1e3},
                         {"allreduce_ms", reduce * 1e3},
                         {"efficiency_gather", compute / (compute + gather)},
                         {"efficiency_allreduce", compute / (compute + reduce)}});
    }
    result["model"] = model;
    result["parameters"] = options.parameters;
    result["step_seconds"] = options.stepSeconds;
    return result;
}

}  // namespace dejag::bench
