// dejag/bench: the renderer's cost (dejag bench render): ms per frame for colour only and for every
// buffer, the ground truth's cost with and without adaptive accumulation (with its accuracy), and each
// texture sampler's cost beside its aliasing and the detail it keeps.
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
    // The texture samplers on the receding planes, each textures': ms per frame, and the aliasing and
    // detail kept (data/spectrum.h) against a truth of point samples (the texels averaged over the pixel).
    std::vector<std::string> samplerTextures = {"checker", "stripes", "text"};
    std::pair<int, int> samplerSize = {512, 512};
    int samplerTruthSamples = 256;
};

// One JSON object per case; progress lines go to stderr.
std::vector<nlohmann::json> benchRender(const RenderBenchOptions& options);

}  // namespace dejag::bench
