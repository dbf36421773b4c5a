// dejag/base: SplitMix64, the small deterministic hash/generator every stage uses for its seeds (the same
// numbers on every machine and compiler, unlike the standard library's distributions).
#pragma once

#include <cstdint>

namespace dejag {

// SplitMix64's step: add the golden-ratio increment, then mix (a bijection of 64-bit values).
inline uint64_t splitMix64(uint64_t z) {
    z += 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

// A uniform double in [low, high) from the top 53 bits of a 64-bit value.
inline double unitInterval(uint64_t bits, double low = 0.0, double high = 1.0) {
    return low + (high - low) * double(bits >> 11) * 0x1.0p-53;
}

}  // namespace dejag
