// dejag/bench: the thesis' comparison reproduced (dejag bench taa): the static test (16 frames of
// history on each scene, then No AA, FXAA, U-TAA, T-TAA, taa-hq and the oracle — the mean of the
// frames' in-pixel samples — against the accumulated truth) and the ghosting test (moving objects, every
// frame against the truth of its pose, with flicker).
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "infer/filter.h"

namespace dejag::bench {

struct TaaBenchOptions {
    int width = 800, height = 450;  // the thesis used 1600x900; half in each direction by default
    int truthSamples = 128;
    int historyFrames = 16;
    bool ghosting = true;
    int ghostFrames = 100;
    int ghostWidth = 400, ghostHeight = 225, ghostTruthSamples = 32;
    std::string ssimMapFolder;  // when set, the static test's SSIM maps go there as PNGs
    bool quiet = false;
    infer::FilterParameters taaHq;  // taa-hq's parameters (dejag bench taa --set NAME=VALUE)
};

// One JSON object per (test, scene, method): metrics on 8-bit sRGB images like the thesis'.
std::vector<nlohmann::json> benchTaa(const TaaBenchOptions& options);

}  // namespace dejag::bench
