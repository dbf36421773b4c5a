#include "train/temporal.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "base/error.h"

namespace dejag::train {

TemporalLayout temporalLayout(const nn::Model& model) {
    TemporalLayout layout;
    layout.history = model.outputChannels();
    layout.depth = model.inputChannels() == layout.inputChannels() + 2;
    if (layout.history < 3 || model.inputChannels() != layout.inputChannels())
        throw Error("model '" + model.name() + "' is not a temporal network: it takes " +
                    std::to_string(model.inputChannels()) + " channels and returns " +
                    std::to_string(model.outputChannels()) +
                    " (one returning 3 + S channels takes 3 + (3 + S) + 2 + 2: colour, history, motion, "
                    "jitter; or 2 more: depth, previous depth)");
    return layout;
}

void makeTemporalInput(nn::Tensor& input, const data::SequenceFrame& frame, const nn::Tensor* previous,
                       const TemporalLayout& layout) {
    const int64_t N = frame.colour.dim(0), P = frame.colour.dim(2), Q = frame.colour.dim(3), plane = P * Q;
    const int64_t C = layout.inputChannels(), H = layout.history;
    const nn::Shape shape{N, C, P, Q};
    if (input.shape() != shape) input = nn::Tensor(shape);
    for (int64_t n = 0; n < N; ++n) {
        float* in = input.data() + n * C * plane;
        const float* colour = frame.colour.data() + n * 3 * plane;
        std::memcpy(in, colour, size_t(3 * plane) * sizeof(float));
        float* history = in + 3 * plane;
        if (previous && !frame.fresh[size_t(n)]) {
            std::memcpy(history, previous->data() + n * H * plane, size_t(H * plane) * sizeof(float));
        } else {
            std::memcpy(history, colour, size_t(3 * plane) * sizeof(float));
            std::fill(history + 3 * plane, history + H * plane, 0.0f);
        }
        std::memcpy(in + (3 + H) * plane, frame.motion.data() + n * 2 * plane,
                    size_t(2 * plane) * sizeof(float));
        std::fill(in + (5 + H) * plane, in + (6 + H) * plane, frame.jitter[size_t(2 * n)]);
        std::fill(in + (6 + H) * plane, in + (7 + H) * plane, frame.jitter[size_t(2 * n + 1)]);
        if (layout.depth) {
            if (frame.depth.numel() == 0 || frame.previousDepth.numel() == 0)
                throw Error("this temporal network takes depth: the sequences' depth was not loaded");
            const float* depth = frame.depth.data() + n * plane;
            std::memcpy(in + (7 + H) * plane, depth, size_t(plane) * sizeof(float));
            const float* before =
                previous && !frame.fresh[size_t(n)] ? frame.previousDepth.data() + n * plane : depth;
            std::memcpy(in + (8 + H) * plane, before, size_t(plane) * sizeof(float));
        }
    }
}

namespace {

// The RGB planes (the first 3 of each item) of an (N, H, P, Q) tensor, and back.
void takeRgb(nn::Tensor& rgb, const nn::Tensor& all) {
    const int64_t N = all.dim(0), H = all.dim(1), plane = all.dim(2) * all.dim(3);
    const nn::Shape shape{N, 3, all.dim(2), all.dim(3)};
    if (rgb.shape() != shape) rgb = nn::Tensor(shape);
    for (int64_t n = 0; n < N; ++n)
        std::memcpy(rgb.data() + n * 3 * plane, all.data() + n * H * plane,
                    size_t(3 * plane) * sizeof(float));
}
void addRgb(nn::Tensor& all, const nn::Tensor& rgb) {
    const int64_t N = all.dim(0), H = all.dim(1), plane = all.dim(2) * all.dim(3);
    for (int64_t n = 0; n < N; ++n)
        for (int64_t i = 0; i < 3 * plane; ++i)
            all.data()[n * H * plane + i] += rgb.data()[n * 3 * plane + i];
}

}  // namespace

Unroller::Unroller(nn::Model& model, TemporalLoss loss)
    : model_(model), loss_(std::move(loss)), layout_(temporalLayout(model)) {
    model_.setInputGradient(true);
}

double Unroller::run(const data::SequenceBatch& batch, bool backward) {
    const int K = int(batch.frames.size());
    if (K < 1) throw Error("a sequence batch needs frames");
    const nn::Tensor& first = batch.frames[0].colour;
    const int64_t N = first.dim(0), P = first.dim(2), Q = first.dim(3), plane = P * Q, H = layout_.history;
    const nn::SsimLossDesc desc{N, 3, P, Q, 1.0};
    inputs_.resize(size_t(K)), outputs_.resize(size_t(K));
    // The temporal term: per continuing item and frame pair, the mean |(X_t - X_t-1) - (R_t - R_t-1)| over
    // its RGB values, averaged over every item and pair of the batch.
    const double pairs = double(N) * double(std::max(K - 1, 1));
    const double frameScale = 1.0 / K;
    double total = 0;
    for (int t = 0; t < K; ++t) {
        const data::SequenceFrame& f = batch.frames[size_t(t)];
        makeTemporalInput(inputs_[size_t(t)], f, t > 0 ? &outputs_[size_t(t - 1)] : nullptr, layout_);
        const nn::Tensor& out = model_.forward(inputs_[size_t(t)]);
        // A frame whose output is not finite (a diverging step) makes a history the next frame cannot
        // take: the loss is NaN, and the guard skips the step.
        for (int64_t i = 0; i < out.numel(); ++i)
            if (!std::isfinite(out.data()[i])) return std::nan("");
        if (outputs_[size_t(t)].shape() != out.shape()) outputs_[size_t(t)] = nn::Tensor(out.shape());
        std::memcpy(outputs_[size_t(t)].data(), out.data(), size_t(out.numel()) * sizeof(float));
        takeRgb(rgb_, out);
        total += frameScale * loss_.perFrame.evaluate<float>(nullptr, rgb_.data(), f.truth.data(), desc);
        if (loss_.temporalWeight > 0 && t > 0) {
            const nn::Tensor& before = outputs_[size_t(t - 1)];
            const data::SequenceFrame& g = batch.frames[size_t(t - 1)];
            for (int64_t n = 0; n < N; ++n) {
                if (f.fresh[size_t(n)]) continue;
                double sum = 0;
                for (int64_t i = 0; i < 3 * plane; ++i)
                    sum += std::abs(
                        double(out.data()[n * H * plane + i]) - before.data()[n * H * plane + i] -
                        (double(f.truth.data()[n * 3 * plane + i]) - g.truth.data()[n * 3 * plane + i]));
                total += loss_.temporalWeight * sum / (3.0 * double(plane)) / pairs;
            }
        }
    }
    if (!backward) return total;

    std::vector<float>& sum = gradientSum_;
    sum.assign(size_t(model_.parameterCount()), 0.0f);
    const nn::Shape outShape = outputs_[0].shape();
    if (carried_.shape() != outShape) carried_ = nn::Tensor(outShape);
    carried_.zero();  // the gradient w.r.t. frame t's output from the frames after it
    for (int t = K - 1; t >= 0; --t) {
        const data::SequenceFrame& f = batch.frames[size_t(t)];
        if (t != K - 1) model_.forward(inputs_[size_t(t)]);  // this frame's activations again
        if (dout_.shape() != outShape) dout_ = nn::Tensor(outShape);
        std::memcpy(dout_.data(), carried_.data(), size_t(carried_.numel()) * sizeof(float));
        takeRgb(rgb_, outputs_[size_t(t)]);
        if (drgb_.shape() != rgb_.shape()) drgb_ = nn::Tensor(rgb_.shape());
        drgb_.zero();
        loss_.perFrame.evaluate<float>(drgb_.data(), rgb_.data(), f.truth.data(), desc, frameScale);
        addRgb(dout_, drgb_);
        carried_.zero();
        if (loss_.temporalWeight > 0 && t > 0) {
            const nn::Tensor &now = outputs_[size_t(t)], &before = outputs_[size_t(t - 1)];
            const data::SequenceFrame& g = batch.frames[size_t(t - 1)];
            const double scale = loss_.temporalWeight / (3.0 * double(plane)) / pairs;
            for (int64_t n = 0; n < N; ++n) {
                if (f.fresh[size_t(n)]) continue;
                for (int64_t i = 0; i < 3 * plane; ++i) {
                    const int64_t at = n * H * plane + i;
                    const double d =
                        double(now.data()[at]) - before.data()[at] -
                        (double(f.truth.data()[n * 3 * plane + i]) - g.truth.data()[n * 3 * plane + i]);
                    const float s = float(d > 0 ? scale : d < 0 ? -scale : 0.0);
                    dout_.data()[at] += s, carried_.data()[at] -= s;
                }
            }
        }
        model_.backward(dout_);
        const float* g = model_.gradientData();
        for (size_t i = 0; i < sum.size(); ++i) sum[i] += g[i];
        // What this frame's history input passes to the frame before (nothing where it restarted).
        if (t > 0) {
            const nn::Tensor& dinput = model_.inputGradient();
            const int64_t C = layout_.inputChannels();
            for (int64_t n = 0; n < N; ++n) {
                if (f.fresh[size_t(n)]) continue;
                const float* from = dinput.data() + (n * C + 3) * plane;
                float* to = carried_.data() + n * H * plane;
                for (int64_t i = 0; i < H * plane; ++i) to[i] += from[i];
            }
        }
    }
    std::copy(sum.begin(), sum.end(), model_.gradientData());
    return total;
}

}  // namespace dejag::train
