// dejag/bench: the demo behind `make demo` — every anti-aliasing method on a set of rendered scenes,
// scored against their supersampled truth, with an HTML report.
//
// For each scene: a still frame (no AA, FXAA, the networks) and 16 Halton-jittered frames of history
// (U-TAA, T-TAA), all against the 64-sample adaptive truth of the same view. Scores: PSNR and SSIM on
// whole images, edge pixels and texture pixels (data/evaluation.h); ms per frame, median of repeats.
// Writes OUT/report.html (side-by-side zoomed crops and SSIM maps per scene), OUT/mosaic.png,
// OUT/pareto.png (ms against PSNR), OUT/results.csv and OUT/results.json.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace dejag::bench {

struct DemoOptions {
    std::string out = "out/demo";
    int width = 640, height = 360;
    int truthSamples = 64;
    int historyFrames = 16;
    int repeat = 3;                   // timing repeats per method and scene
    std::vector<std::string> scenes;  // empty: the default set
    std::vector<std::string> models;  // model files; missing ones are skipped with a note
    // The moving sequence: the temporal network ("" or a missing file: the section is skipped with a
    // note) next to no AA, FXAA and taa-hq on `movingFrames` frames of `movingScene` panning 1 px a frame,
    // jittered with `movingJitterSpread`.
    std::string temporalModel = "models/dejag-temporal.safetensors";
    std::string movingScene = "atrium";
    int movingFrames = 24;
    double movingJitterSpread = 1.0;
    bool quiet = false;
};

// The default scene set: the held-out test families first (atrium, hard-edges, flowers), then a few
// trained-on families in new poses (pipe, text-wall, planes).
std::vector<std::string> defaultDemoScenes();

// Runs the demo; returns one row per (scene, method) plus a "mean" row per method, and in `moving` (when
// given) one row per method of the moving sequence: mean PSNR and SSIM over its frames from the 8th on,
// and the flicker.
std::vector<nlohmann::json> runDemo(const DemoOptions& options,
                                    std::vector<nlohmann::json>* moving = nullptr);

}  // namespace dejag::bench
