#include "infer/cnn_temporal.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "base/error.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "infer/cnn.h"
#include "infer/cnn_temporal_kernels.h"
#include "nn/inference.h"
#include "nn/kernel_filter_kernels.h"
#include "nn/layers.h"
#include "nn/model.h"

namespace dejag::nn {
namespace {
// The kernel filter's row kernel at the active SIMD level.
void blendRow(const KernelFilterRowArgs& args) {
    DEJAG_SIMD_CALL(kernelFilterRow, args);
}
// The head's 1x1 convolution and pixel shuffle fused: one output row's logits from the trunk's features.
void headLogitsRow(const KernelLogitsRowArgs& args) {
    DEJAG_SIMD_CALL(kernelLogitsRow, args);
}
}  // namespace
}  // namespace dejag::nn

namespace dejag::infer {
namespace {
using nn::blendRow;
using nn::headLogitsRow;

class CnnTemporalFilter final : public Filter {
  public:
    // stillTrust: the trust at or above which the accumulate family's pixel whose 3x3 neighbourhood does
    // not move keeps the whole history (a negative value: never). clip: "auto" (the model's), "on", "off".
    CnnTemporalFilter(nn::Model model, nn::InferencePrecision precision, const std::string& path,
                      float stillTrust = -1.0f, const std::string& gate = "off",
                      const std::string& clip = "auto")
        : Filter("cnn-temporal"), model_(std::move(model)), precision_(precision) {
        history_ = model_.outputChannels();
        depthInput_ = model_.inputChannels() == 3 + history_ + 6;
        if (history_ < 3 || (model_.inputChannels() != 3 + history_ + 4 && !depthInput_))
            throw Error("model '" + model_.name() + "' is not a temporal network: it takes " +
                        std::to_string(model_.inputChannels()) + " channels and returns " +
                        std::to_string(model_.outputChannels()) +
                        " (a recurrent network returning 3 + S takes 3 + (3 + S) + 2 + 2, or 2 more with "
                        "depth)");
        figures_.settings = {{"model", path}, {"precision", precisionName(precision)}, {"gate", gate}};
        accumulate_ = model_.architecture().value("name", "") == "accumulate";
        trunk_ = builtinTrunk(model_, headFused_);
        if (headFused_) takeHead();
        if (trunk_) multiple_ = int64_t(1) << model_.architecture()["family"]["depth"].get<int>();
        warpedChannels_ = accumulate_ ? 4 : history_;
        if (accumulate_ && trunk_) maxCount_ = model_.architecture()["family"].value("max_count", 32.0f);
        for (const nlohmann::json& node : model_.architecture()["nodes"])
            if (node.value("name", "") == "blended") centreBias_ = node.value("centre_bias", 0.0f);
        // ρ = min(1, 2 σ(l)) >= τ where l >= log(τ / (2 - τ)).
        if (accumulate_ && trunk_ && stillTrust >= 0.0f)
            stillLogit_ = stillTrust <= 0.0f ? -INFINITY : std::log(stillTrust / (2.0f - stillTrust));
        const bool modelClips = accumulate_ && model_.architecture()["family"].value("clip", false);
        clip_ = clip == "on" || (clip == "auto" && modelClips);
        if (clip != "auto" && clip_ != modelClips && !(accumulate_ && trunk_))
            throw Error("clip=" + clip + " is for a network of the built-in accumulate family");
        figures_.settings.push_back({"clip", clip_ ? "on" : "off"});
    }
    // A network that takes depth reads it where the frames have it (depth and previous depth); without, it
    // sees both 0: no surface changed, the history judged by its colours alone.
    BufferSet needs() const override { return unsigned(Buffer::Motion); }
    BufferSet uses() const override {
        return depthInput_ ? Buffer::Motion | Buffer::Depth | Buffer::PreviousDepth | Buffer::Jitter
                           : Buffer::Motion | Buffer::Jitter;
    }
    bool temporal() const override { return true; }
    void reset() override { fresh_ = true; }

  private:
    // The built-in temporal family (nn/model.cpp, exactly as Model::builtinArchitecture makes it) is run
    // in three parts: the history's warp on planar planes; the nodes from "seen" to "head" (the U-Net
    // and its 1x1 head, all at 1/2 but the first conv's input) as an inference plan of their own; and
    // the head's pixel shuffle, the blend of the frame's 3x3 neighbourhood with the warped history and
    // the state's correction fused in one row kernel fed as the plan hands over each row of the head.
    // Nothing but the warp and the blend touches a full-resolution tensor of more than the input's
    // channels. The accumulate family runs the same way: its warped history is the kept mean and its
    // confidence (4 floats a pixel), and its sink blends them with accumulatePixel. Other temporal
    // networks (any JSON graph) run as one plan.
    //
    // Where the head has exactly the 10 logits of 4 phases (no state channels), the trunk stops at the
    // head's input and the sink computes each output row's logits from those features (the 1x1
    // convolution and the shuffle fused, kernelLogitsRow): the 40-channel head is never stored.
    static std::optional<nn::Model> builtinTrunk(const nn::Model& model, bool& headFused) {
        headFused = false;
        const nlohmann::json& a = model.architecture();
        const std::string family = a.value("name", "");
        if ((family != "temporal" && family != "accumulate") || !a.contains("family")) return std::nullopt;
        nn::ModelOptions options;
        options.width = a["family"].value("width", 0), options.depth = a["family"].value("depth", 0);
        options.state = family == "accumulate" ? 1 : a["family"].value("state", -1);
        options.maxCount = a["family"].value("max_count", 32.0f);
        options.depthInput = a["family"].value("depth_input", false);
        options.clip = a["family"].value("clip", false);
        nlohmann::json builtin;
        try {
            builtin = nn::Model::builtinArchitecture(family, options);
        } catch (const Error&) {
            return std::nullopt;
        }
        if (builtin["nodes"] != a["nodes"] || builtin["output"] != a["output"] || options.state > 1)
            return std::nullopt;  // (the fused path keeps the history in 4 floats a pixel)
        nlohmann::json nodes = nlohmann::json::array();
        std::string output = "head";
        bool inside = false;
        for (nlohmann::json node : a["nodes"]) {
            if (inside) {
                for (auto& input : node["inputs"])
                    if (input == "seen") input = "input";
                if (node["name"] == "head" && node.value("out_channels", 0) == 4 * 10 &&
                    node.value("kernel", 0) == 1 && node.value("stride", 1) == 1 &&
                    node.value("activation", "none") == "none" && node["inputs"].size() == 1) {
                    headFused = true, output = node["inputs"][0].get<std::string>();
                    break;
                }
                nodes.push_back(node);
                if (node["name"] == "head") break;
            }
            inside = inside || node["name"] == "seen";
        }
        nn::Model trunk = nn::Model::fromArchitecture(
            {{"name", "temporal-trunk"},
             {"input_channels",
              3 + (3 + options.state) + 2 + (family == "accumulate" ? 2 : 0) + (options.depthInput ? 2 : 0)},
             {"init", a.value("init", "he_normal")},
             {"nodes", nodes},
             {"output", output}});
        for (const nn::ParameterInfo& p : trunk.parameters()) {
            const nn::ParameterInfo& from = model.parameter(p.name);
            std::copy_n(model.parameterData() + from.offset, nn::shapeNumel(p.shape),
                        trunk.parameterData() + p.offset);
        }
        return trunk;
    }

    // The fused head's weights as kernelLogitsRow reads them: per row phase py, tap j and column phase px
    // (the shuffle's channel (2 j + py) 2 + px), the input channels' weights; the biases alike.
    void takeHead() {
        const nn::ParameterInfo& weight = model_.parameter("head.weight");
        headChannels_ = int(weight.shape[1]);
        const float* w = model_.parameterData() + weight.offset;
        const float* b = model_.parameterData() + model_.parameter("head.bias").offset;
        headWeights_.resize(size_t(40 * headChannels_)), headBias_.resize(40);
        for (int py = 0; py < 2; ++py)
            for (int j = 0; j < 10; ++j)
                for (int px = 0; px < 2; ++px) {
                    const int channel = (2 * j + py) * 2 + px, slot = (py * 10 + j) * 2 + px;
                    headBias_[size_t(slot)] = b[channel];
                    std::copy_n(w + channel * headChannels_, headChannels_,
                                headWeights_.data() + slot * headChannels_);
                }
    }

    // The history's row kernel's inputs for one output row y (the head's rows at y / 2 given; with the
    // head fused, the head's input features).
    struct BlendSink final : nn::OutputRowSink {
        CnnTemporalFilter* self = nullptr;
        const Frame* frame = nullptr;
        float* out = nullptr;
        void row(int64_t, int64_t y2, const float* const* head) override { blend(y2, head, 1); }
        // The head's rows as the plan holds them (blocked): no conversion of the whole head first.
        bool takesStridedRows() const override { return true; }
        void rowStrided(int64_t, int64_t y2, const float* const* head, int64_t stride) override {
            blend(y2, head, stride);
        }
        // Head channel c's value at s is head[c][s * stride].
        void blend(int64_t y2, const float* const* head, int64_t stride) {
            CnnTemporalFilter& f = *self;
            // The planes are of the padded size (W, H); the frame's own size is (frameW, frameH).
            const int64_t W = f.paddedWidth_, H = f.paddedHeight_, plane = W * H;
            const int64_t frameW = f.width_, frameH = f.height_;
            const int S = f.history_ - 3, C = frame->channels;
            thread_local std::vector<float> logits, blended, stillRow;
            logits.resize(size_t(10 * W)), blended.resize(size_t(3 * W));
            // The fused head reads the features blocked: channel c at features + (c / block) blockStride +
            // s block + c % block. Rows laid out otherwise are copied so first.
            nn::KernelLogitsRowArgs logitArgs;
            if (f.headFused_) {
                const int inC = f.headChannels_;
                const int64_t blockStride = inC > stride ? head[stride] - head[0] : 0;
                bool blocked = true;
                for (int c = 0; c < inC; ++c)
                    blocked = blocked && head[c] == head[0] + (c / stride) * blockStride + c % stride;
                logitArgs.features = head[0], logitArgs.block = int(stride),
                logitArgs.blockStride = blockStride;
                if (!blocked) {
                    thread_local std::vector<float> features;
                    features.resize(size_t(inC * (W / 2)));
                    for (int64_t s = 0; s < W / 2; ++s)
                        for (int c = 0; c < inC; ++c) features[size_t(s * inC + c)] = head[c][s * stride];
                    logitArgs.features = features.data(), logitArgs.block = inC, logitArgs.blockStride = 0;
                }
                logitArgs.inChannels = inC, logitArgs.taps = 10, logitArgs.factor = 2;
                logitArgs.width = W, logitArgs.logits = logits.data();
            }
            for (int dy = 0; dy < 2; ++dy) {
                const int64_t y = 2 * y2 + dy;
                if (f.headFused_) {
                    logitArgs.weights = f.headWeights_.data() + dy * 20 * f.headChannels_;
                    logitArgs.bias = f.headBias_.data() + dy * 20;
                    headLogitsRow(logitArgs);
                }
                // The shuffle: output channel k at (2 y2 + dy, 2 s + dx) is head channel 4 k + 2 dy + dx at
                // s.
                for (int k = 0; k < 10 && !f.headFused_; ++k) {
                    const float* even = head[4 * k + 2 * dy];
                    const float* odd = head[4 * k + 2 * dy + 1];
                    float* l = logits.data() + k * W;
                    for (int64_t s = 0; s < W / 2; ++s)
                        l[2 * s] = even[s * stride], l[2 * s + 1] = odd[s * stride];
                }
                const float* in[9];
                const float* history[3];
                float* rgb[3];
                for (int c = 0; c < 3; ++c) {
                    for (int d = -1; d <= 1; ++d)
                        in[c * 3 + d + 1] =
                            f.frame_.data() + c * plane + std::clamp<int64_t>(y + d, 0, H - 1) * W;
                    history[c] = f.warped_.data() + c * plane + y * W;
                    rgb[c] = blended.data() + c * W;
                }
                nn::KernelFilterRowArgs args;
                args.out = rgb, args.in = in, args.logits = logits.data(), args.width = W;
                args.channels = 3, args.kernel = 3, args.centreBias = f.centreBias_;
                args.history = history;
                float* next = f.previous_.data() + y * W * 4;
                if (f.accumulate_) {  // the next history (kept mean and confidence) straight into `next`
                    args.keptInterleaved = next, args.confidence = f.warped_.data() + 3 * plane + y * W;
                    args.maxCount = f.maxCount_;
                    args.clip = f.clip_;
                    if (f.gateStill_) {
                        stillRow.resize(size_t(W));
                        f.stillRow(y, stillRow.data());
                        args.still = stillRow.data(), args.stillLogit = *f.stillLogit_;
                        args.stillTolerance = kStillTolerance;
                    }
                }
                // Accumulate's kernel writes, for frames of 3 or 4 channels, the output's pixels itself.
                const bool shownByKernel = f.accumulate_ && (C == 3 || C == 4);
                if (f.accumulate_) {
                    if (shownByKernel && y < frameH) {  // (the padding's rows: to rgb, not shown)
                        args.shownInterleaved = out + y * frameW * C;
                        args.shownChannels = C, args.shownWidth = frameW;
                        args.shownPass = frame->colour + y * frameW * C;
                    }
                }
                blendRow(args);
                if (shownByKernel) continue;
                // The next history, interleaved: the blend's RGB and the warped state plus its correction.
                if (!f.accumulate_) {
                    for (int64_t x = 0; x < W; ++x)
                        for (int c = 0; c < 3; ++c) next[4 * x + c] = rgb[c][x];
                }
                if (S == 1 && !f.accumulate_) {
                    const float* even = head[4 * 10 + 2 * dy];
                    const float* odd = head[4 * 10 + 2 * dy + 1];
                    const float* warped = f.warped_.data() + 3 * plane + y * W;
                    for (int64_t s2 = 0; s2 < W / 2; ++s2) {  // (W is even: a multiple of the coarsest scale)
                        next[8 * s2 + 3] = warped[2 * s2] + even[s2 * stride];
                        next[8 * s2 + 7] = warped[2 * s2 + 1] + odd[s2 * stride];
                    }
                }
                if (y >= frameH) continue;
                float* o = out + y * frameW * C;
                const float* colour = frame->colour + y * frameW * C;
                for (int64_t x = 0; x < frameW; ++x) {
                    for (int c = 0; c < 3; ++c) o[x * C + c] = std::clamp(rgb[c][x], 0.0f, 1.0f);
                    for (int c = 3; c < C; ++c) o[x * C + c] = colour[x * C + c];
                }
            }
        }
    };

    // The still gate (accumulate family): where the pixel and its 8 neighbours do not move, now and in the
    // previous frame (where the history comes from: an object that has just left a still background is in
    // its history), the network trusts the history at least τ and the history's colours lie within the
    // frame's 3x3 range (widened by kStillTolerance, linear), the pixel keeps its whole history (full
    // trust, no clip), so a still view keeps its running mean of up to max_count samples (training's
    // sequences are too short to teach trust beyond a few frames; docs/infer.md). The range test sends
    // back to the network a still pixel whose light changed. The row kernel decides; this marks the pixels
    // whose neighbourhood does not move (moving_ and previousMoving_: the pixels whose motion exceeds
    // kStillMotion, this frame's and the previous one's).
    static constexpr float kStillMotion = 1e-3f, kStillTolerance = 2.0f / 255.0f;
    void stillRow(int64_t y, float* still) const {
        const int64_t W = paddedWidth_, H = paddedHeight_;
        const uint8_t* rows[6];
        for (int d = -1; d <= 1; ++d) {
            const int64_t row = std::clamp<int64_t>(y + d, 0, H - 1) * W;
            rows[d + 1] = moving_.data() + row, rows[d + 4] = previousMoving_.data() + row;
        }
        // The six rows' flags ORed column by column, then each column with its neighbours (plain loops the
        // compiler vectorizes).
        thread_local std::vector<uint8_t> column;
        column.resize(size_t(W));
        uint8_t* c = column.data();
        for (int64_t x = 0; x < W; ++x)
            c[x] = uint8_t(rows[0][x] | rows[1][x] | rows[2][x] | rows[3][x] | rows[4][x] | rows[5][x]);
        still[0] = (c[0] | c[std::min<int64_t>(1, W - 1)]) ? 0.0f : 1.0f;
        for (int64_t x = 1; x + 1 < W; ++x) still[x] = (c[x - 1] | c[x] | c[x + 1]) ? 0.0f : 1.0f;
        if (W > 1) still[W - 1] = (c[W - 2] | c[W - 1]) ? 0.0f : 1.0f;
    }

    // The trunk's input rows from the frame's and the warped history's planes.
    struct InputRows final : nn::InputRowSource {
        CnnTemporalFilter* self = nullptr;
        float jitter[2] = {0, 0};
        const float* motion = nullptr;  // interleaved, of the padded size
        bool fresh = false;
        void row(int64_t, int64_t y, float* const* channels) override {
            const CnnTemporalFilter& f = *self;
            const int64_t W = f.paddedWidth_, plane = W * f.paddedHeight_;
            const int S = f.warpedChannels_;
            for (int c = 0; c < 3; ++c) std::copy_n(f.frame_.data() + c * plane + y * W, W, channels[c]);
            for (int c = 0; c < S; ++c) std::copy_n(f.warped_.data() + c * plane + y * W, W, channels[3 + c]);
            for (int k = 0; k < 2; ++k) std::fill_n(channels[3 + S + k], W, jitter[k]);
            int next = 5 + S;
            if (f.accumulate_) {  // the motion, clamped to +-4 px (0 where the history restarts)
                const float* m = motion + y * W * 2;
                for (int k = 0; k < 2; ++k, ++next)
                    for (int64_t x = 0; x < W; ++x)
                        channels[next][x] = fresh ? 0.0f : std::clamp(m[2 * x + k], -4.0f, 4.0f);
            }
            if (f.depthInput_)  // the frame's depth and the previous frame's, warped
                for (int k = 0; k < 2; ++k, ++next)
                    std::copy_n(f.depth_.data() + k * plane + y * W, W, channels[next]);
        }
    };

    // The fused path works on planes of the frame padded (edges repeated) to a multiple of the trunk's
    // coarsest scale: the frame, the motion and so the history.
    void processFused(const Frame& frame, float* out) {
        const int64_t W = paddedWidth_, H = paddedHeight_, frameW = frame.width, frameH = frame.height;
        const int C = frame.channels, S = warpedChannels_;
        const int64_t plane = W * H;
        const int inputs = 3 + S + 2 + (accumulate_ ? 2 : 0) + (depthInput_ ? 2 : 0);
        const nn::Shape shape{1, inputs, H, W};
        const bool padded = W != frameW || H != frameH;
        if (!fused_ || fused_->inputShape() != shape) {
            fused_.emplace(*trunk_, shape, precision_);
            frame_ = nn::Tensor({3, H, W}), warped_ = nn::Tensor({S, H, W});
            motion_ = padded ? nn::Tensor({H, W, 2}) : nn::Tensor();
            // Depth: the frame's and the previous frame's warped, as planes; the previous frame's as it came.
            depth_ = depthInput_ ? nn::Tensor({2, H, W}) : nn::Tensor();
            previousDepth_ = depthInput_ ? nn::Tensor({H, W}) : nn::Tensor();
            moving_.assign(stillLogit_ ? size_t(plane) : 0, 0);
            previousMoving_.assign(moving_.size(), 1);
        }
        const bool fresh = fresh_;
        std::swap(moving_, previousMoving_);  // the previous frame's flags kept; this one's made below
        gateStill_ = stillLogit_.has_value() && !fresh;
        const bool hasDepth = frame.depth && frame.previousDepth;
        // The frame as planes, the motion padded, the moving pixels marked, the depth copied: rows of the
        // padded size, the frame's last row and column repeated.
        parallelFor(0, H, 16, [&](int64_t first, int64_t last) {
            for (int64_t y = first; y < last; ++y) {
                const int64_t q = std::min(y, frameH - 1) * frameW;
                TemporalPrepassRow row;
                row.colour = frame.colour + q * C, row.channels = C, row.frameWidth = frameW, row.width = W;
                for (int c = 0; c < 3; ++c) row.planes[c] = frame_.data() + c * plane + y * W;
                row.motion = frame.motion + 2 * q;
                row.motionOut = padded ? motion_.data() + 2 * y * W : nullptr;
                row.moving = moving_.empty() ? nullptr : moving_.data() + y * W;
                row.stillMotion = kStillMotion;
                if (depthInput_) {
                    row.depth = hasDepth ? frame.depth + q : nullptr;
                    row.previousDepth = hasDepth ? frame.previousDepth + q : nullptr;
                    row.depthOut = depth_.data() + y * W,
                    row.previousDepthOut = previousDepth_.data() + y * W;
                }
                DEJAG_SIMD_CALL(temporalPrepassRow, row);
            }
        });
        // (A frame where everything moves has no still pixel: the row kernel then skips the gate's test.)
        if (gateStill_) gateStill_ = std::find(moving_.begin(), moving_.end(), uint8_t(0)) != moving_.end();
        if (depthInput_) {  // the previous frame's depth where each pixel was (where the history restarts,
                            // this one's)
            if (fresh) {
                std::copy_n(depth_.data(), plane, depth_.data() + plane);
            } else {
                nn::warpPlane(depth_.data() + plane, previousDepth_.data(),
                              padded ? motion_.data() : frame.motion, W, H, nn::WarpFilter::Bilinear);
            }
        }
        // The history (interleaved, 4 floats a pixel) read where each pixel was, as planes; on a fresh start
        // the frame and zero state (accumulate's: nothing kept, as training's fresh history).
        if (fresh) {
            if (accumulate_)
                std::fill_n(warped_.data(), S * plane, 0.0f);
            else
                std::copy_n(frame_.data(), 3 * plane, warped_.data());
            std::fill_n(warped_.data() + 3 * plane, (S - 3) * plane, 0.0f);
        } else {
            float* planes[4];
            for (int c = 0; c < S; ++c) planes[c] = warped_.data() + c * plane;
            nn::warpInterleaved(planes, previous_.data(), padded ? motion_.data() : frame.motion, W, H, S,
                                nn::WarpFilter::CatmullRom);
        }
        // The trunk's input: frame, warped history, jitter; streamed a band of rows at a time where the plan
        // can take it so.
        InputRows rows;
        rows.self = this, rows.jitter[0] = frame.hasJitter ? frame.jitter[0] : 0.0f;
        rows.jitter[1] = frame.hasJitter ? frame.jitter[1] : 0.0f;
        rows.motion = padded ? motion_.data() : frame.motion, rows.fresh = fresh;
        BlendSink sink;
        sink.self = this, sink.frame = &frame, sink.out = out;
        if (fused_->canStreamInput()) {
            fused_->runStreamed(rows, sink, 0, (H + 1) / 2);
        } else {
            parallelFor(0, H, 16, [&](int64_t first, int64_t last) {
                float* channels[3 + 4 + 2 + 2 + 2];
                for (int64_t y = first; y < last; ++y) {
                    for (int c = 0; c < inputs; ++c) channels[c] = fused_->inputRow(0, c, y);
                    rows.row(0, y, channels);
                }
            });
            fused_->runInPlace(sink, 0, (H + 1) / 2);
        }
        fresh_ = false;
    }

    void process(const Frame& frame, float* out) override {
        if (frame.width != width_ || frame.height != height_) {  // a new size: the history starts over
            width_ = frame.width, height_ = frame.height, fresh_ = true;
            paddedWidth_ = (width_ + multiple_ - 1) / multiple_ * multiple_;
            paddedHeight_ = (height_ + multiple_ - 1) / multiple_ * multiple_;
            // 4 floats a pixel of the padded size for the fused path; planes of the frame's size otherwise.
            previous_ = nn::Tensor({std::max(history_, 4), paddedHeight_, paddedWidth_});
        }
        if (trunk_) return processFused(frame, out);
        const int W = frame.width, H = frame.height, C = frame.channels, S = history_;
        const int64_t plane = int64_t(W) * H, channels = 3 + S + 4 + (depthInput_ ? 2 : 0);
        const nn::Shape shape{1, channels, H, W};
        if (!plan_ || input_.shape() != shape) {
            plan_.emplace(model_, shape, precision_);
            input_ = nn::Tensor(shape);
        }
        float* in = input_.data();
        const float* colour = frame.colour;
        const float* motion = frame.motion;
        const bool fresh = fresh_;
        const bool hasDepth = frame.depth && frame.previousDepth;
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
                    if (depthInput_)
                        in[(7 + S) * plane + p] = hasDepth ? frame.depth[p] : 0.0f,
                                             in[(8 + S) * plane + p] = !hasDepth ? 0.0f
                                                                       : fresh   ? frame.depth[p]
                                                                                 : frame.previousDepth[p];
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
    // The fused path (builtinTrunk): the trunk, its plan, and the frame, warped history and motion as
    // planes (previous_ holds the history).
    std::optional<nn::Model> trunk_;
    std::optional<nn::InferencePlan> fused_;
    bool headFused_ = false;  // the trunk ends at the head's input; the sink computes the logits
    int headChannels_ = 0;
    std::vector<float> headWeights_, headBias_;  // [row phase][tap][column phase][headChannels_]
    nn::Tensor frame_, warped_, motion_;
    int64_t width_ = 0, height_ = 0, paddedWidth_ = 0, paddedHeight_ = 0;
    int64_t multiple_ = 1;  // the fused path's sizes: multiples of 2^depth
    float centreBias_ = 0.0f;
    bool accumulate_ = false;  // the accumulate family (nn/model.cpp)
    int warpedChannels_ = 3;   // what the fused path warps: the history's, or accumulate's kept mean and s
    float maxCount_ = 32.0f;
    bool depthInput_ = false;           // the model takes depth and previous depth (accumulate +depth)
    nn::Tensor depth_, previousDepth_;  // the fused path's (padded)
    std::optional<float> stillLogit_;   // the still gate's trust logit (none: off)
    bool gateStill_ = false;            // this frame's
    bool clip_ = false;            // the history clamped to the frame's 3x3 range (the model's, or forced)
    std::vector<uint8_t> moving_;  // the still gate's: 1 where a pixel moves (padded)
    std::vector<uint8_t> previousMoving_;  // ... in the previous frame (all 1 before the first)
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
        {"gate", "auto",
         "off | auto (0) | T: where nothing moves in a pixel's 3x3 neighbourhood (now and in the previous "
         "frame), the network trusts the history at least T in [0, 1] and the history lies within the "
         "frame's 3x3 range, keep all of it (accumulate networks)"},
        {"clip", "auto",
         "auto (as the network was trained) | on | off: clamp the history to the frame's 3x3 range "
         "(accumulate networks)"},
    };
    spec.needs = unsigned(Buffer::Motion);
    spec.optional =
        Buffer::Depth | Buffer::PreviousDepth | Buffer::Jitter;  // depth: for a network that reads it
    spec.temporal = true;
    spec.make = [](MethodParameters& p) -> std::unique_ptr<Filter> {
        const nn::InferencePrecision precision = cnnPrecision(p.text("precision"));
        const std::string path = p.path("model");
        const std::string gate = p.text("gate");
        float stillTrust = -1.0f;
        if (gate == "auto") {
            stillTrust = 0.0f;
        } else if (gate != "off") {
            char* end = nullptr;
            const double t = std::strtod(gate.c_str(), &end);
            if (gate.empty() || *end != '\0' || !(t >= 0 && t <= 1))
                throw Error(p.origin("gate") + ": '" + gate + "' is not off, auto or a trust in [0, 1]");
            stillTrust = float(t);
        }
        const std::string clip = p.text("clip");
        if (clip != "auto" && clip != "on" && clip != "off")
            throw Error(p.origin("clip") + ": '" + clip + "' is not auto, on or off");
        nn::Model model = nn::loadModel(path);
        try {
            return std::make_unique<CnnTemporalFilter>(std::move(model), precision, path, stillTrust, gate,
                                                       clip);
        } catch (const Error& e) {
            throw Error("--model '" + path + "': " + e.what());
        }
    };
    return spec;
}

}  // namespace dejag::infer
