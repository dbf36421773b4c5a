// dejag/bench: every method's GPU form against its CPU filter on the same rendered frames
// (dejag bench glsl): the GPU form's passes timed one by one through an off-screen OSMesa context, or the
// context a caller gives, beside the CPU filter's time, with the OpenGL renderer named.
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace dejag::bench {

struct GlslBenchOptions {
    int width = 960, height = 540;
    int repeat = 5;  // timed frames after two warm-up frames
    std::vector<std::string> methods = {"none",      "fxaa",   "smaa", "taa",
                                        "taa-sobel", "taa-hq", "cnn",  "cnn-temporal"};
    // Resolves the methods' model paths (the shipped networks from any folder).
    std::function<std::string(const std::string&)> pathResolver;
};

// One JSON object per method: method, gpu_ms and cpu_ms (medians), their ratio, the GPU passes' medians
// ("passes": name, ms), the renderer, whether it is emulated on the CPU, and what the two forms do
// differently ("differences").
std::vector<nlohmann::json> benchGlsl(const GlslBenchOptions& options);

}  // namespace dejag::bench
