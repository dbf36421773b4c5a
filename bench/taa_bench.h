// dejag/bench: the thesis' comparison reproduced (dejag bench taa): the static test (16 frames of
// history on each scene, then No AA, FXAA, U-TAA, T-TAA, taa-hq and the oracle — the mean of the
// frames' in-pixel samples — against the accumulated truth) and the ghosting test (moving objects, every
// frame against the truth of its pose, with flicker).
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "infer/filter.h"
#include "render/renderer.h"
#include "render/scene.h"

namespace dejag::bench {

struct TaaBenchOptions {
    int width = 800, height = 450;  // the thesis used 1600x900; half in each direction by default
    int truthSamples = 128;
    int historyFrames = 64;  // the thesis' program never reset its history: a settled one is scored
    bool ghosting = true;
    int ghostFrames = 100;
    int ghostWidth = 400, ghostHeight = 225, ghostTruthSamples = 32;  // the sequences' (ghosting, moving)
    // The moving protocol: still scenes under camera pans and an orbit, `movingFrames` frames each, scored
    // from frame `movingSkip` on (the histories fill first).
    bool moving = true;
    int movingFrames = 40, movingSkip = 8;
    std::vector<std::string> movingScenes = {"pipe", "atrium", "flowers", "hard-edges"};
    // The truth averaged as 8-bit displayed (sRGB-encoded) values, as the thesis' accumulation buffer
    // did, instead of in linear light.
    bool displayTruth = false;
    bool unjitter = true;       // U-TAA and T-TAA un-jitter the current frame first (their `unjitter`)
    std::string ssimMapFolder;  // when set, the static test's SSIM maps go there as PNGs
    bool quiet = false;
    infer::FilterParameters taaHq;  // taa-hq's parameters (dejag bench taa --set NAME=VALUE)
    // The networks, compared when their model files are given: the temporal one (cnn-temporal) as a TAA,
    // the single-frame one (cnn) on each jittered frame.
    std::string temporalModel, fastModel;
    infer::FilterParameters temporal;  // cnn-temporal's other parameters (dejag bench taa --temporal-set)
    double jitterSpread = 1.7;         // the frames' Halton jitter: the offsets' spread in pixels
    // Only these scenes (a static label such as "pipe tilted", or a scene such as "flowers", which
    // names it in every test); empty: all.
    std::vector<std::string> scenes;
};

// A rendered frame's buffers as the filters take them (colour and albedo sRGB-encoded, depth over the
// far plane, the jitter as the image's shift in pixels, +y down); `frame` points into the vectors.
struct FrameBuffers {
    FrameBuffers(const render::Frame& f, float far, const render::Vec2& jitter);
    FrameBuffers(const FrameBuffers&) = delete;
    std::vector<float> colour, albedo, depth, motion, ids, previousDepth;
    infer::Frame frame;
};

// A still scene seen by a moving camera: a pan to the right (or an orbit around the target) of `speed`
// pixels a frame at the target's distance, for frames `height` pixels high.
void moveCamera(render::Scene& scene, double speed, bool orbit, int height);

// Frame `index` of a jittered sequence at scene time `time`: Halton point index mod 16 with `spread`,
// every buffer.
render::FrameRequest jitteredFrame(double time, int index, double spread);

// One JSON object per (test, scene, method): metrics on 8-bit sRGB images like the thesis'.
std::vector<nlohmann::json> benchTaa(const TaaBenchOptions& options);

}  // namespace dejag::bench
