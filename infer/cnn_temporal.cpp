#include "infer/cnn_temporal.h"

#include <algorithm>
#include <cstring>
#include <optional>
#include <string>

#include "base/error.h"
#include "base/thread_pool.h"
#include "infer/cnn.h"
#include "nn/inference.h"
#include "nn/model.h"

namespace dejag::infer {
namespace {

class CnnTemporalFilter final : public Filter {
  public:
    CnnTemporalFilter(nn::Model model, nn::InferencePrecision precision, const std::string& path)
        : Filter("cnn-temporal"), model_(std::move(model)), precision_(precision) {
        history_ = model_.outputChannels();
        if (history_ < 3 || model_.inputChannels() != 3 + history_ + 4)
            throw Error("model '" + model_.name() + "' is not a temporal network: it takes " +
                        std::to_string(model_.inputChannels()) + " channels and returns " +
                        std::to_string(model_.outputChannels()) +
                        " (a recurrent network returning 3 + S takes 3 + (3 + S) + 2 + 2)");
        figures_.settings = {{"model", path}, {"precision", precisionName(precision)}};
    }
    BufferSet needs() const override { return unsigned(Buffer::Motion); }
    bool temporal() const override { return true; }
    void reset() override { fresh_ = true; }

  private:
    void process(const Frame& frame, float* out) override {
        const int W = frame.width, H = frame.height, C = frame.channels, S = history_;
        const int64_t plane = int64_t(W) * H, channels = 3 + S + 4;
        const nn::Shape shape{1, channels, H, W};
        if (!plan_ || input_.shape() != shape) {
            plan_.emplace(model_, shape, precision_);
            input_ = nn::Tensor(shape);
            previous_ = nn::Tensor({1, S, H, W});
            fresh_ = true;
        }
        float* in = input_.data();
        const float* colour = frame.colour;
        const float* motion = frame.motion;
        const bool fresh = fresh_;
        // The input planes: colour, history (the previous output, or the colour and zeros), motion (0
        // where the history restarts), jitter.
        parallelFor(0, H, 16, [&](int64_t first, int64_t last) {
            for (int64_t y = first; y < last; ++y)
                for (int64_t x = 0; x < W; ++x) {
                    const int64_t p = y * W + x;
                    for (int c = 0; c < 3; ++c) {
                        const float v = colour[p * C + c];
                        in[c * plane + p] = v;
                        if (fresh) in[(3 + c) * plane + p] = v;
                    }
                    if (fresh)
                        for (int c = 3; c < S; ++c) in[(3 + c) * plane + p] = 0.0f;
                    else
                        for (int c = 0; c < S; ++c) in[(3 + c) * plane + p] = previous_.data()[c * plane + p];
                    in[(3 + S) * plane + p] = fresh ? 0.0f : motion[2 * p];
                    in[(4 + S) * plane + p] = fresh ? 0.0f : motion[2 * p + 1];
                    in[(5 + S) * plane + p] = frame.hasJitter ? frame.jitter[0] : 0.0f;
                    in[(6 + S) * plane + p] = frame.hasJitter ? frame.jitter[1] : 0.0f;
                }
        });
        const nn::Tensor& result = plan_->run(input_);
        const float* r = result.data();
        parallelFor(0, H, 16, [&](int64_t first, int64_t last) {
            for (int64_t y = first; y < last; ++y)
                for (int64_t x = 0; x < W; ++x) {
                    const int64_t p = y * W + x;
                    for (int c = 0; c < 3; ++c) out[p * C + c] = std::clamp(r[c * plane + p], 0.0f, 1.0f);
                    for (int c = 3; c < C; ++c) out[p * C + c] = colour[p * C + c];
                }
        });
        std::memcpy(previous_.data(), r, size_t(S * plane) * sizeof(float));
        fresh_ = false;
    }

    nn::Model model_;
    nn::InferencePrecision precision_;
    int history_ = 3;
    std::optional<nn::InferencePlan> plan_;
    nn::Tensor input_, previous_;
    bool fresh_ = true;
};

}  // namespace

MethodSpec cnnTemporalMethod() {
    MethodSpec spec;
    spec.name = "cnn-temporal";
    spec.summary =
        "a recurrent network (models/dejag-temporal.safetensors) on whole frames: the frame, its own "
        "previous output warped by the motion, and the jitter in; the frame and the next history out";
    spec.parameters = {
        {"model", "models/dejag-temporal.safetensors", "the model file (a temporal network)"},
        {"precision", "auto", "fp32 | bf16 (AVX-512 BF16 CPUs) | auto (bf16 where the CPU has it)"},
    };
    spec.needs = unsigned(Buffer::Motion);
    spec.temporal = true;
    spec.make = [](MethodParameters& p) -> std::unique_ptr<Filter> {
        const nn::InferencePrecision precision = cnnPrecision(p.text("precision"));
        const std::string path = p.path("model");
        nn::Model model = nn::loadModel(path);
        try {
            return std::make_unique<CnnTemporalFilter>(std::move(model), precision, path);
        } catch (const Error& e) {
            throw Error("--model '" + path + "': " + e.what());
        }
    };
    return spec;
}

}  // namespace dejag::infer
