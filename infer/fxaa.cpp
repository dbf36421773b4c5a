#include "infer/fxaa.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "base/error.h"
#include "base/thread_pool.h"
#include "infer/fxaa_kernels.h"

namespace dejag::infer {

// The search steps of FXAA 3.11's quality presets.
std::vector<float> fxaaPresetSteps(int preset) {
    switch (preset) {
        case 12:
            return {1.0f, 1.5f, 2.0f, 4.0f, 12.0f};
        case 23:
            return {1.0f, 1.5f, 2.0f, 2.0f, 2.0f, 8.0f};
        case 39:
            return {1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.5f, 2.0f, 2.0f, 2.0f, 2.0f, 4.0f, 8.0f};
        default:
            throw Error("FXAA preset " + std::to_string(preset) + " is not one of 12, 23, 39");
    }
}

namespace {}  // namespace

Fxaa::Fxaa(const FxaaOptions& options) : options_(options), steps_(fxaaPresetSteps(options.preset)) {
    for (const float v : {options.subpix, options.edgeThreshold, options.edgeThresholdMin})
        if (!(v >= 0.0f && v <= 1.0f)) throw Error("FXAA: subpix and edge thresholds must be in [0, 1]");
}

void Fxaa::apply(const float* in, float* out, int width, int height, int channels) {
    if (width < 1 || height < 1 || channels < 3) throw Error("FXAA needs an image with R, G, B channels");
    const size_t floats = size_t(width) * size_t(height) * size_t(channels);
    if (in != out)  // the same buffer: filtered in place
        parallelFor(0, int64_t(floats), 1 << 18, [&](int64_t first, int64_t last) {
            std::memcpy(out + first, in + first, size_t(last - first) * sizeof(float));
        });
    applyInPlace(out, width, height, channels);
}

void Fxaa::applyInPlace(float* frame, int width, int height, int channels) {
    if (width < 1 || height < 1 || channels < 3) throw Error("FXAA needs an image with R, G, B channels");
    if (size_t(width) * size_t(height) * size_t(channels) > size_t(INT32_MAX))
        throw Error("FXAA: image too large (" + std::to_string(width) + "x" + std::to_string(height) + ")");
    FxaaKernelArgs args;
    args.frame = frame, args.width = width, args.height = height, args.channels = channels;
    args.lumaStride = fxaaLumaStride(width);
    // (+64: the kernels' windowed reads of a row may run up to 47 floats past the last row's pixels.)
    const size_t lumaFloats = args.lumaStride * size_t(height) + 64;
    if (luma_.size() < lumaFloats) luma_.resize(lumaFloats);
    args.luma = luma_.data();
    args.greenAsLuma = options_.greenAsLuma;
    args.edgeThreshold = options_.edgeThreshold, args.edgeThresholdMin = options_.edgeThresholdMin;
    args.subpix = options_.subpix;
    args.steps = steps_.data(), args.stepCount = int(steps_.size());
    // Eight bands per thread balance the load; each band makes two luma rows of its neighbours again.
    const int bandCount = std::min(8 * threadCount(), height);
    if (int(bands_.size()) < bandCount) bands_.resize(size_t(bandCount));
    auto lumaRow = [&](int y) { return luma_.data() + size_t(y) * args.lumaStride + kFxaaLumaPad; };

    // 1. Per band: the luma rows, each row's contrast test as soon as the row below exists (the rows just
    // outside the band are made again in the band's own two spare rows, so bands stay independent).
    parallelFor(0, bandCount, 1, [&](int64_t firstBand, int64_t lastBand) {
        for (int64_t b = firstBand; b < lastBand; ++b) {
            Band& band = bands_[size_t(b)];
            const int y0 = int(int64_t(height) * b / bandCount),
                      y1 = int(int64_t(height) * (b + 1) / bandCount);
            if (band.spare.size() < 2 * args.lumaStride) band.spare.resize(2 * args.lumaStride);
            float* above = band.spare.data() + kFxaaLumaPad;
            float* below = above + args.lumaStride;
            if (y0 > 0) DEJAG_SIMD_CALL(fxaaLumaRow, args, y0 - 1, above);
            DEJAG_SIMD_CALL(fxaaLumaRow, args, y0, lumaRow(y0));
            int count = 0;
            for (int y = y0; y < y1; ++y) {
                const float* down = lumaRow(y);  // the last row's own row below it
                if (y + 1 < y1) {
                    DEJAG_SIMD_CALL(fxaaLumaRow, args, y + 1, lumaRow(y + 1));
                    down = lumaRow(y + 1);
                } else if (y + 1 < height) {
                    DEJAG_SIMD_CALL(fxaaLumaRow, args, y + 1, below);
                    down = below;
                }
                const float* up = y > y0 ? lumaRow(y - 1) : (y0 > 0 ? above : lumaRow(y));
                if (band.xs.size() < size_t(count + width)) {
                    band.xs.resize(size_t(count + width)), band.ys.resize(size_t(count + width));
                }
                const int found =
                    DEJAG_SIMD_CALL(fxaaEdgesInRow, args, up, lumaRow(y), down, band.xs.data() + count);
                std::fill(band.ys.begin() + count, band.ys.begin() + count + found, y);
                count += found;
            }
            band.count = count;
            if (band.rgb.size() < 3 * size_t(count)) band.rgb.resize(3 * size_t(count));
        }
    });
    // 2. The search and the new colours (reads luma anywhere in the frame: after every band's step 1), in
    // chunks of the bands' pixel lists laid end to end, so the threads share the work evenly however the
    // edges are spread over the bands.
    int64_t processed = 0;
    for (int b = 0; b < bandCount; ++b) processed += bands_[size_t(b)].count;
    constexpr int64_t kChunk = 256;
    parallelFor(0, (processed + kChunk - 1) / kChunk, 1, [&](int64_t firstChunk, int64_t lastChunk) {
        int64_t begin = firstChunk * kChunk, end = std::min(lastChunk * kChunk, processed);
        int64_t bandStart = 0;  // global index of the band's first pixel
        for (int b = 0; b < bandCount && begin < end; ++b) {
            Band& band = bands_[size_t(b)];
            const int64_t bandEnd = bandStart + band.count;
            if (begin < bandEnd) {
                const int64_t first = begin - bandStart, last = std::min(end, bandEnd) - bandStart;
                DEJAG_SIMD_CALL(fxaaResolve, args, band.xs.data() + first, band.ys.data() + first,
                                int(last - first), band.rgb.data() + 3 * first);
                begin = bandStart + last;
            }
            bandStart = bandEnd;
        }
    });
    processedFraction_ = double(processed) / (double(width) * double(height));
    // 3. The new colours into the frame, once nothing reads it any more.
    parallelFor(0, bandCount, 1, [&](int64_t firstBand, int64_t lastBand) {
        for (int64_t b = firstBand; b < lastBand; ++b) {
            const Band& band = bands_[size_t(b)];
            for (int i = 0; i < band.count; ++i) {
                float* pixel =
                    frame + (size_t(band.ys[size_t(i)]) * size_t(width) + size_t(band.xs[size_t(i)])) *
                                size_t(channels);
                std::memcpy(pixel, band.rgb.data() + 3 * size_t(i), 3 * sizeof(float));
            }
        }
    });
}

namespace {

class FxaaFilter final : public Filter {
  public:
    explicit FxaaFilter(const FxaaOptions& options) : Filter("fxaa"), fxaa_(options) {
        figures_.settings = {{"preset", std::to_string(options.preset)}};
    }
    BufferSet needs() const override { return 0; }

  private:
    void process(const Frame& frame, float* out) override {
        fxaa_.apply(frame.colour, out, frame.width, frame.height, frame.channels);
        figures_.processedFraction = fxaa_.processedFraction();
    }
    Fxaa fxaa_;
};

}  // namespace

FxaaOptions fxaaOptions(const MethodParameters& p) {
    FxaaOptions options;
    options.preset = p.integer("preset", 0, 99);
    options.greenAsLuma = p.flag("green-luma");
    options.subpix = float(p.number("subpix", 0, 1));
    options.edgeThreshold = float(p.number("edge-threshold", 0, 1));
    options.edgeThresholdMin = float(p.number("edge-threshold-min", 0, 1));
    return options;
}

MethodSpec fxaaMethod() {
    const FxaaOptions d;
    MethodSpec spec;
    spec.name = "fxaa";
    spec.summary = "FXAA 3.11 quality (Lottes 2011): edge search along luma steps, one frame, no buffers";
    spec.parameters = {
        {"preset", std::to_string(d.preset), "quality preset: 12, 23 or 39 (the search steps)"},
        {"green-luma", d.greenAsLuma ? "true" : "false",
         "use green as luma instead of 0.299 R + 0.587 G + 0.114 B"},
        {"subpix", "0.75", "amount of sub-pixel aliasing removal, [0, 1]"},
        {"edge-threshold", "0.166", "minimum local contrast relative to the local maximum, [0, 1]"},
        {"edge-threshold-min", "0.0833", "minimum absolute local contrast (skips dark areas), [0, 1]"},
    };
    spec.make = [](MethodParameters& p) -> std::unique_ptr<Filter> {
        const FxaaOptions options = fxaaOptions(p);
        try {
            return std::make_unique<FxaaFilter>(options);
        } catch (const Error& e) {
            throw Error(p.origin("preset") + ": " + e.what());
        }
    };
    return spec;
}

}  // namespace dejag::infer
