// dejag/nn: the finite-difference gradient check that tests/nn/gradcheck_test.cpp and `dejag bench
// stability` run on every layer and loss: an analytic gradient (double) against central differences of
// a scalar function of the same values.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <vector>

namespace dejag::nn {

// n values uniform in [low, high).
template <class Rng>
std::vector<double> randomValues(size_t n, Rng& rng, double low = -1.0, double high = 1.0) {
    std::uniform_real_distribution<double> u(low, high);
    std::vector<double> v(n);
    for (double& x : v) x = u(rng);
    return v;
}

inline double dot(const std::vector<double>& a, const std::vector<double>& b) {
    double s = 0.0;
    for (size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
    return s;
}

struct GradientCheckOptions {
    int samples = 40;           // coordinates checked (all of them if there are fewer)
    double step = 1e-5;         // central difference step h
    double floor = 1e-6;        // least denominator of the relative error
    double floorOfLargest = 0;  // ... or this fraction of the gradient's largest component, if larger
    bool piecewise = false;     // skip coordinates on a kink (one-sided differences disagree)
};

struct GradientCheckResult {
    double worst = 0;  // largest relative error |numeric - analytic| / max(floor, |numeric| + |analytic|)
    int checked = 0, kinks = 0;
};

// Compares `analytic` (dscalar/dv) with central differences of scalar() at coordinates of v drawn from
// rng; v is restored.
inline GradientCheckResult checkGradient(std::vector<double>& v, const std::vector<double>& analytic,
                                         const std::function<double()>& scalar, std::mt19937_64& rng,
                                         const GradientCheckOptions& options = {}) {
    GradientCheckResult result;
    double largest = 0.0;
    for (const double g : analytic) largest = std::max(largest, std::abs(g));
    const double floor = std::max(options.floor, options.floorOfLargest * largest);
    const double h = options.step, base = options.piecewise ? scalar() : 0.0;
    const size_t n = v.size();
    for (int s = 0; s < options.samples && s < int(n); ++s) {
        const size_t i = n <= size_t(options.samples) ? size_t(s) : size_t(rng() % n);
        const double saved = v[i];
        v[i] = saved + h;
        const double plus = scalar();
        v[i] = saved - h;
        const double minus = scalar();
        v[i] = saved;
        if (options.piecewise) {
            const double forward = (plus - base) / h, backward = (base - minus) / h;
            if (std::abs(forward - backward) >
                1e-3 * std::max({std::abs(forward), std::abs(backward), 1e-6})) {
                ++result.kinks;
                continue;
            }
        }
        const double numeric = (plus - minus) / (2 * h);
        result.worst = std::max(result.worst, std::abs(numeric - analytic[i]) /
                                                  std::max(floor, std::abs(numeric) + std::abs(analytic[i])));
        ++result.checked;
    }
    return result;
}

}  // namespace dejag::nn
