// dejag/bench: which tool fixes which aliasing (dejag bench texture, docs/texture-aa.md). On texture and
// shading scenes — the receding planes with a checker, stripes and text, and the bumpy normal-mapped
// plate — every way dejag has to fight the aliasing, scored against one supersampled truth each:
//   at the source: the texture samplers (point, bilinear, trilinear, anisotropic x16, Fourier) and the
//   normal map read by its standard chain or by super bump mapping;
//   after rendering: FXAA, SMAA and the single-frame networks on the default frame (trilinear; the
//   standard normal map);
//   over time: U-TAA, T-TAA, taa-hq and the temporal network on a still view's jittered frames, both of
//   the default frames and of point-sampled ones.
// Each row: aliasing (data/spectrum.h) and detail kept, PSNR in linear light, and the cost in ms a frame
// (the render plus the filter); a row no other row of its scene beats on both cost and PSNR is on the
// Pareto front.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace dejag::bench {

struct TextureBenchOptions {
    int width = 384, height = 384;
    int truthSamples = 256;
    int frames = 16;  // the temporal methods' still history; the last frame is scored
    double jitterSpread = 1.0;
    std::vector<std::string> cases = {"checker", "stripes", "text", "normal-map"};
    std::vector<std::string> models;  // single-frame networks (cnn), each a row
    std::string temporalModel;        // cnn-temporal, when given
    bool quiet = false;
};

std::vector<nlohmann::json> benchTexture(const TextureBenchOptions& options);

// Marks each row "pareto": true when no other row of its "case" has both a lower "ms" and a higher "psnr".
void markPareto(std::vector<nlohmann::json>& rows);

}  // namespace dejag::bench
