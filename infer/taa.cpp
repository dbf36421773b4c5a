#include "infer/taa.h"

#include <algorithm>
#include <cmath>

#include "base/error.h"
#include "base/thread_pool.h"
#include "infer/taa_kernels.h"

namespace dejag::infer {

Taa::Taa(const TaaOptions& options) : options_(options) {
    if (!(options.feedbackMin >= 0 && options.feedbackMin <= options.feedbackMax && options.feedbackMax < 1))
        throw Error("TAA feedback must satisfy 0 <= min <= max < 1");
    if (!(options.motionBlurScale >= 0 && options.motionBlurScale <= 100) ||
        options.motionBlurMaxSamples < 1 || options.motionBlurMaxSamples > 256)
        throw Error("TAA motion blur: the scale must be in [0, 100] and the samples in 1..256");
}

void Taa::apply(const TaaFrame& frame, float* out) {
    const TaaFrame& f = frame;
    // Un-jittering (the thesis' shaders read the current frame at p + jitter) happens in the kernel.
    // (A jitter that is not a number is no jitter; one beyond the frame reads its border.)
    const bool unjitter = options_.unjitter && frame.hasJitter && std::isfinite(frame.jitter[0]) &&
                          std::isfinite(frame.jitter[1]) && (frame.jitter[0] != 0 || frame.jitter[1] != 0);
    const int W = f.width, H = f.height;
    if (W < 1 || H < 1 || !f.colour || !f.depth || !f.motion)
        throw Error("TAA needs colour, depth and motion buffers");
    const bool improved = options_.improved;
    if (improved && (!f.albedo || !f.ids || !f.previousDepth))
        throw Error("the Sobel-improved TAA needs albedo, IDs and the previous depth too");
    if (size_t(W) * size_t(H) * 3 > size_t(INT32_MAX))
        throw Error("TAA: frame too large (" + std::to_string(W) + "x" + std::to_string(H) + ")");
    // Four bands per thread balance the load; each band recomputes a few rows of its neighbours.
    const int bands = std::min(H, 4 * threadCount());
    const bool fresh = W != width_ || H != height_;
    if (fresh) {
        width_ = W, height_ = H;
        stride_ = (size_t(W) + 15) / 16 * 16 + 16;  // full vectors at the end of a row stay inside it
        const size_t plane = stride_ * size_t(H);
        // (+32: the kernel's windowed reads may run past the last row's end; what they read there is unused)
        history_.assign(plane * 3 + 32, 0.0f), nextHistory_.assign(plane * 3 + 32, 0.0f);
        sobel_.assign(plane + 32, 0.0f), nextSobel_.assign(plane + 32, 0.0f);
    }
    if (fresh || bands != bands_) {
        bands_ = bands;
        scratch_.assign(taaScratchFloats(W) * size_t(bands), 0.0f);
    }
    TaaBandInputs in;
    in.width = W, in.height = H;
    in.colour = f.colour, in.albedo = f.albedo, in.depth = f.depth, in.motion = f.motion;
    in.ids = f.ids, in.previousDepth = f.previousDepth;
    in.history = history_.data(), in.nextHistory = nextHistory_.data();
    in.sobelHistory = sobel_.data(), in.nextSobelHistory = nextSobel_.data();
    in.stride = stride_, in.planeFloats = stride_ * size_t(H);
    in.out = out;
    in.improved = improved, in.sharpen = options_.sharpen, in.fresh = fresh;
    in.feedbackMin = options_.feedbackMin, in.feedbackMax = options_.feedbackMax;
    in.depthThreshold = options_.depthThreshold;
    in.unjitter = unjitter;
    if (unjitter)
        in.jitterX = std::clamp(f.jitter[0], -float(W), float(W)),
        in.jitterY = std::clamp(f.jitter[1], -float(H), float(H));
    const size_t scratchFloats = taaScratchFloats(W);
    parallelFor(0, bands, 1, [&](int64_t first, int64_t last) {
        for (int64_t b = first; b < last; ++b) {
            const int y0 = int(int64_t(H) * b / bands), y1 = int(int64_t(H) * (b + 1) / bands);
            DEJAG_SIMD_CALL(taaBand, in, y0, y1, scratch_.data() + size_t(b) * scratchFloats);
        }
    });
    std::swap(history_, nextHistory_);
    if (improved) std::swap(sobel_, nextSobel_);
    if (options_.motionBlur) blurAlongMotion(f, out);
}

void Taa::blurAlongMotion(const TaaFrame& f, float* out) {
    const int W = f.width, H = f.height;
    const size_t floats = size_t(W) * size_t(H) * 3;
    if (unblurred_.size() != floats) unblurred_.assign(floats, 0.0f);  // on a size change only
    parallelFor(0, H, 16, [&](int64_t first, int64_t last) {
        std::copy(out + size_t(first) * size_t(W) * 3, out + size_t(last) * size_t(W) * 3,
                  unblurred_.begin() + std::ptrdiff_t(size_t(first) * size_t(W) * 3));
    });
    TaaBlurInputs in;
    in.width = W, in.height = H;
    in.source = unblurred_.data(), in.motion = f.motion, in.out = out;
    in.scale = options_.motionBlurScale, in.maxSamples = options_.motionBlurMaxSamples;
    parallelFor(0, H, 4, [&](int64_t first, int64_t last) {
        DEJAG_SIMD_CALL(taaMotionBlurRows, in, int(first), int(last));
    });
}

namespace {

class TaaFilter final : public Filter {
  public:
    TaaFilter(const TaaOptions& options, BufferSet needs)
        : Filter(options.improved ? "taa-sobel" : "taa"), taa_(options), needs_(needs) {}
    BufferSet needs() const override { return needs_; }
    BufferSet uses() const override { return needs_ | Buffer::Jitter; }
    bool temporal() const override { return true; }
    void reset() override { taa_.reset(); }

  private:
    void process(const Frame& frame, float* out) override {
        TaaFrame f;
        f.width = frame.width, f.height = frame.height;
        f.albedo = frame.albedo, f.depth = frame.depth, f.motion = frame.motion, f.ids = frame.ids;
        f.previousDepth = frame.previousDepth;
        f.hasJitter = frame.hasJitter, f.jitter[0] = frame.jitter[0], f.jitter[1] = frame.jitter[1];
        f.colour = rgb_.rgb(frame);  // TAA works on R G B alone: the other channels pass through
        taa_.apply(f, rgb_.result(frame, out));
        rgb_.finish(frame, out);
    }
    Taa taa_;
    BufferSet needs_;
    RgbScratch rgb_;
};

}  // namespace

TaaOptions taaOptions(const MethodParameters& p, bool improved) {
    TaaOptions options;
    options.improved = improved;
    options.sharpen = p.flag("sharpen");
    options.unjitter = p.flag("unjitter");
    options.motionBlur = p.flag("motion-blur");
    options.motionBlurScale = float(p.number("motion-blur-scale", 0, 100));
    options.feedbackMin = float(p.number("feedback-min", 0, 1));
    options.feedbackMax = float(p.number("feedback-max", 0, 1));
    options.depthThreshold = float(p.number("depth-threshold", 0, 1));
    return options;
}

MethodSpec taaMethod(bool improved) {
    const TaaOptions d;
    MethodSpec spec;
    spec.name = improved ? "taa-sobel" : "taa";
    spec.summary =
        improved ? "T-TAA (docs/taa.md): U-TAA with a stabilised Sobel of albedo, luma and depth, id and "
                   "depth pseudo-variances and a normalised sharpen"
                 : "U-TAA (docs/taa.md): reprojected history blended with the jittered frame, "
                   "clipped to the 3x3 colour box (the Uncharted 4 / INSIDE baseline)";
    spec.parameters = {
        {"sharpen", "true", "the final sharpen (docs/infer.md)"},
        {"unjitter", "true",
         "read the current frame bilinearly at p + jitter first, as the thesis' shaders do (frames with a "
         "jitter)"},
        {"motion-blur", "false", "blur the output along the motion vectors (docs/taa.md step 7)"},
        {"motion-blur-scale", "1", "motion blur length: the frame rate over the target frame rate, [0, 100]"},
        {"feedback-min", "0.925", "history weight where current and history lumas differ"},
        {"feedback-max", "0.979", "history weight where they agree (below 1)"},
        {"depth-threshold", "0.002", "pseudo-variances vanish below this 3x3 depth spread (depth / far)"},
    };
    spec.needs = improved
                     ? Buffer::Depth | Buffer::Motion | Buffer::Albedo | Buffer::Ids | Buffer::PreviousDepth
                     : Buffer::Depth | Buffer::Motion;
    spec.optional = unsigned(Buffer::Jitter);
    spec.temporal = true;
    const BufferSet needs = spec.needs;
    spec.make = [improved, needs](MethodParameters& p) -> std::unique_ptr<Filter> {
        return std::make_unique<TaaFilter>(taaOptions(p, improved), needs);
    };
    return spec;
}

}  // namespace dejag::infer
