// dejag/bench: the post-process filters on a rendered 1920x1080 frame (dejag bench filter).
#pragma once

#include <nlohmann/json.hpp>
#include <vector>

namespace dejag::bench {

struct FilterBenchOptions {
    int width = 1920, height = 1080;
    int repeat = 15;
    std::vector<int> threads = {1, 2};
};

// One JSON object per case: name, threads, ms (median), target_ms, processed_fraction, psnr gain.
std::vector<nlohmann::json> benchFilters(const FilterBenchOptions& options);

}  // namespace dejag::bench
