#include "nn/init.h"

#include <cmath>

namespace dejag::nn {
namespace {

uint64_t splitMix64(uint64_t& x) {
    uint64_t z = (x += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

}  // namespace

Rng::Rng(uint64_t seed, uint64_t stream) {
    uint64_t mix = seed;
    state_ = splitMix64(mix);
    increment_ = (splitMix64(mix) ^ stream) | 1u;
    next();
}

uint32_t Rng::next() {
    const uint64_t old = state_;
    state_ = old * 6364136223846793005ull + increment_;
    const uint32_t xorShifted = uint32_t(((old >> 18u) ^ old) >> 27u);
    const uint32_t rotation = uint32_t(old >> 59u);
    return (xorShifted >> rotation) | (xorShifted << ((32u - rotation) & 31u));
}

float Rng::uniform() {
    return float(next() >> 8) * (1.0f / 16777216.0f);
}

float Rng::uniform(float low, float high) {
    return low + (high - low) * uniform();
}

float Rng::normal() {
    if (haveSpare_) {
        haveSpare_ = false;
        return spare_;
    }
    // Box-Muller on (0, 1] x [0, 1).
    const double u1 = (double(next() >> 8) + 1.0) / 16777216.0;
    const double u2 = double(next() >> 8) / 16777216.0;
    const double radius = std::sqrt(-2.0 * std::log(u1));
    spare_ = float(radius * std::sin(2.0 * M_PI * u2));
    haveSpare_ = true;
    return float(radius * std::cos(2.0 * M_PI * u2));
}

uint32_t Rng::below(uint32_t bound) {
    if (bound == 0) return 0;
    const uint32_t threshold = (0u - bound) % bound;  // Lemire-style rejection of the biased low range
    for (;;) {
        const uint32_t r = next();
        if (r >= threshold) return r % bound;
    }
}

void heNormal(float* weights, int64_t count, int64_t fanIn, Rng& rng) {
    const float deviation = float(std::sqrt(2.0 / double(fanIn)));
    for (int64_t i = 0; i < count; ++i) weights[i] = deviation * rng.normal();
}

void glorotUniform(float* weights, int64_t count, int64_t fanIn, int64_t fanOut, Rng& rng) {
    const float limit = float(std::sqrt(6.0 / double(fanIn + fanOut)));
    for (int64_t i = 0; i < count; ++i) weights[i] = rng.uniform(-limit, limit);
}

}  // namespace dejag::nn
