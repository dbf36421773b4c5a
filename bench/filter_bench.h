// dejag/bench: the post-process filters on a rendered 1920x1080 frame (dejag bench filter).
#pragma once

#include <nlohmann/json.hpp>
#include <vector>

namespace dejag::bench {

struct FilterBenchOptions {
    int width = 1920, height = 1080;
    int repeat = 15;
    std::vector<int> threads = {1, 2};
    // The temporal network (cnn-temporal), timed in float32 and, where the CPU has AVX-512 BF16, in
    // bfloat16 ("": not timed).
    std::string temporalModel;
    // Single-frame networks (cnn), each timed gated and ungated, in float32 and (where the CPU has AVX-512
    // BF16) bfloat16; a guided one also without its guide method (the guide made before the clock).
    std::vector<std::string> frameModels;
};

// One JSON object per case: name, threads, ms (median), target_ms, processed_fraction, psnr gain; floor_ms
// is the memory floor, or for a network the compute floor at the FMA peak measured in this run
// (peak_gmacs, macs_per_pixel).
std::vector<nlohmann::json> benchFilters(const FilterBenchOptions& options);

}  // namespace dejag::bench
