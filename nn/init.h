// dejag/nn: seeded, reproducible random numbers and weight initialisation.
//
// The generator is PCG32 (O'Neill 2014: 64-bit LCG state, XSH-RR output), seeded through SplitMix64 so
// nearby seeds give unrelated streams. Uniform floats take the top 24 bits; normals use Box-Muller. The
// same seed gives the same numbers on every machine and thread count.
#pragma once

#include <cstdint>

namespace dejag::nn {

class Rng {
  public:
    explicit Rng(uint64_t seed, uint64_t stream = 0);
    uint32_t next();
    float uniform();  // [0, 1)
    float uniform(float low, float high);
    float normal();                  // mean 0, standard deviation 1
    uint32_t below(uint32_t bound);  // [0, bound), unbiased

  private:
    uint64_t state_ = 0, increment_ = 0;
    bool haveSpare_ = false;
    float spare_ = 0.0f;
};

// fanIn / fanOut: inputs / outputs per weight including the kernel area (Cin k^2, Cout k^2).
// He (Kaiming) normal, for ReLU layers: N(0, 2 / fanIn).
void heNormal(float* weights, int64_t count, int64_t fanIn, Rng& rng);
// Glorot (Xavier) uniform, Keras' default: U(-sqrt(6 / (fanIn + fanOut)), +sqrt(...)).
void glorotUniform(float* weights, int64_t count, int64_t fanIn, int64_t fanOut, Rng& rng);

}  // namespace dejag::nn
