#include "bench/reach.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>

#include "base/progress.h"
#include "data/evaluation.h"
#include "data/frame_image.h"
#include "infer/filter.h"
#include "infer/smaa.h"
#include "render/renderer.h"

namespace dejag::bench {

const char* reachClassName(int k) {
    static const char* const kNames[kReachClasses] = {"1-3", "4-15", "16-63", "64+", "frame", "texture"};
    return kNames[k];
}

namespace {

int classOf(int length) {
    return length < 4 ? 0 : length < 16 ? 1 : length < 64 ? 2 : 3;
}

struct Sums {
    double squared[kReachClasses] = {};
    int64_t pixels[kReachClasses] = {};
};

nlohmann::json row(const std::string& scene, const std::string& method, int k, const Sums& s,
                   const Sums& none) {
    auto psnr = [&](const Sums& t) {
        const double mse = t.squared[k] / (3.0 * double(std::max<int64_t>(t.pixels[k], 1)));
        return mse > 0 ? 10.0 * std::log10(1.0 / mse) : 100.0;
    };
    return {{"scene", scene},        {"method", method}, {"run", reachClassName(k)},
            {"pixels", s.pixels[k]}, {"psnr", psnr(s)},  {"gain_db", psnr(s) - psnr(none)}};
}

}  // namespace

std::vector<nlohmann::json> benchReach(const ReachBenchOptions& options) {
    const int W = options.width, H = options.height;
    std::vector<std::pair<std::string, std::unique_ptr<infer::Filter>>> methods;
    methods.emplace_back("no AA", infer::makeFilter("none", {}));
    methods.emplace_back("FXAA", infer::makeFilter("fxaa", {}));
    methods.emplace_back("SMAA", infer::makeFilter("smaa", {}));
    for (const std::string& model : options.fastModels)
        methods.emplace_back(
            std::filesystem::path(model).stem().string(),
            infer::makeFilter("cnn", {{"model", model}, {"gate", options.gate ? "auto" : "off"}}));
    // The classes: ultra's edges with the longest search SMAA allows, no diagonal patterns (a diagonal is
    // a run of 1 both ways).
    infer::SmaaOptions classify = infer::smaaPreset("ultra");
    classify.searchSteps = 112, classify.diagonalSteps = 0;
    infer::Smaa smaa(classify);
    const auto context = render::createOsMesaContext();
    std::vector<nlohmann::json> rows;
    std::vector<Sums> pooled(methods.size());
    Progress progress("reach", int64_t(options.scenes.size()), options.quiet);
    for (const std::string& name : options.scenes) {
        const render::Scene scene = render::buildScene(name, {});
        render::Renderer renderer(*context, scene, W, H);
        const RenderedPair pair = renderPair(renderer, options.truthSamples, true);
        const std::vector<float>&aliased = pair.aliased, &truth = pair.truth;
        // The texture region, as the dataset evaluation defines it.
        const data::EvaluationItem regions = data::regionsOfFrame(name, truth, W, H, pair.buffers);
        const Image& texture = regions.masks[int(data::Region::Texture)];
        std::vector<float> scratch(aliased.size());
        smaa.apply(aliased.data(), scratch.data(), W, H, 3);
        // Each pixel's class: the longest run through it or through its neighbour across the edge; -1 off
        // edges.
        std::vector<int8_t> cls(size_t(W) * size_t(H), -1);
        auto mark = [&](int x, int y, int k) {
            int8_t& c = cls[size_t(y) * size_t(W) + size_t(x)];
            c = std::max<int8_t>(c, int8_t(k));
        };
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                const int e = smaa.edgeAt(x, y);
                if (!e) continue;
                const int k = classOf(smaa.runLength(x, y));
                mark(x, y, k);
                if ((e & 2) && y > 0) mark(x, y - 1, k);
                if ((e & 1) && x > 0) mark(x - 1, y, k);
            }
        infer::Frame frame;
        frame.width = W, frame.height = H, frame.colour = aliased.data();
        std::vector<Sums> sums(methods.size());
        std::vector<float> out(aliased.size());
        for (size_t m = 0; m < methods.size(); ++m) {
            methods[m].second->apply(frame, out.data());
            for (size_t p = 0; p < cls.size(); ++p) {
                double squared = 0;
                for (size_t c = 0; c < 3; ++c) {
                    const double d = double(out[3 * p + c]) - double(truth[3 * p + c]);
                    squared += d * d;
                }
                sums[m].squared[kFrameClass] += squared, ++sums[m].pixels[kFrameClass];
                if (texture.pixels[p] > 0.5f)
                    sums[m].squared[kTextureClass] += squared, ++sums[m].pixels[kTextureClass];
                if (cls[p] >= 0) sums[m].squared[cls[p]] += squared, ++sums[m].pixels[cls[p]];
            }
            for (int k = 0; k < kReachClasses; ++k)
                pooled[m].squared[k] += sums[m].squared[k], pooled[m].pixels[k] += sums[m].pixels[k];
        }
        for (int k = 0; k < kReachClasses; ++k)
            for (size_t m = 0; m < methods.size(); ++m)
                rows.push_back(row(name, methods[m].first, k, sums[m], sums[0]));
        progress.advance();
    }
    progress.finish();
    for (int k = 0; k < kReachClasses; ++k)
        for (size_t m = 0; m < methods.size(); ++m)
            rows.push_back(row("all", methods[m].first, k, pooled[m], pooled[0]));
    return rows;
}

}  // namespace dejag::bench
