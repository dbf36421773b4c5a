// dejag/bench: the renderer's cost (dejag bench render): ms per frame for colour only and for every
// buffer, and the ground truth's cost with and without adaptive accumulation (with its accuracy).
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace dejag::bench {

struct RenderBenchOptions {
    std::vector<std::string> scenes = {"pipe", "atrium", "hairball-lit"};
    std::vector<std::pair<int, int>> sizes = {{800, 800}, {1920, 1080}};
    int repeat = 5;
    int truthSamples = 128;
    std::pair<int, int> truthSize = {800, 800};
    std::vector<std::string> truthScenes = {"pipe", "atrium", "hard-edges"};
};

// One JSON object per case; progress lines go to stderr.
std::vector<nlohmann::json> benchRender(const RenderBenchOptions& options);

}  // namespace dejag::bench
