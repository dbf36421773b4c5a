// dejag/bench: where along an edge each single-frame method gains (dejag bench reach). Every pixel on an
// aliased edge (SMAA's edge detection) is classed by the length of the edge's run through it (SMAA's
// search, up to 224 pixels), together with the pixel across the edge; the squared error of no AA, FXAA,
// SMAA and the single-frame network is summed per class against the supersampled truth. Long runs of
// nearly horizontal or vertical edges need a reach along the edge that a network's receptive field may
// not have; this measures it.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace dejag::bench {

struct ReachBenchOptions {
    int width = 1920, height = 1080;
    std::vector<std::string> scenes = {"atrium", "pipe", "hard-edges", "flowers", "hairball"};
    int truthSamples = 64;
    std::vector<std::string> fastModels;  // single-frame networks, each named by its file's stem
    bool gate = true;                     // the networks gated as dejag filter runs them
    bool quiet = false;
};

// The run-length classes: runs of 1-3, 4-15, 16-63 and 64 or more pixels; then two more rows per
// scene and method: "frame" (every pixel) and "texture" (data/evaluation.h's texture region: detailed
// pixels at least 3 px from a geometric edge), where a method must not do harm.
inline constexpr int kReachClasses = 6;
inline constexpr int kFrameClass = 4, kTextureClass = 5;
const char* reachClassName(int k);

// One row per scene (and "all": the scenes pooled), method and class: pixels, psnr (of those pixels'
// RGB), gain_db over no AA's. A "frame" row's psnr is the frame's; pooled, the scenes' pixels together.
std::vector<nlohmann::json> benchReach(const ReachBenchOptions& options);

}  // namespace dejag::bench
