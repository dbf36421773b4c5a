#include "data/metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "base/error.h"
#include "base/thread_pool.h"
#include "data/colormap.h"
#include "data/metrics_kernels.h"

namespace dejag {
namespace {

constexpr double kK1 = 0.01, kK2 = 0.03, kSigma = 1.5;  // docs/metrics.md

void requireSameShape(const Image& reference, const Image& test) {
    if (reference.width != test.width || reference.height != test.height)
        throw Error("the test image is " + std::to_string(test.width) + "x" + std::to_string(test.height) +
                    " but the reference is " + std::to_string(reference.width) + "x" +
                    std::to_string(reference.height));
    if (reference.channels() != test.channels())
        throw Error("the test image has " + std::to_string(test.channels()) +
                    " channels but the reference has " + std::to_string(reference.channels()));
    if (reference.pixels.size() != reference.sampleCount() || test.pixels.size() != test.sampleCount())
        throw Error("pixel buffer does not match the image size");
}

std::vector<uint8_t> selectedPixels(const Image& mask, const Image& reference) {
    if (mask.width != reference.width || mask.height != reference.height)
        throw Error("the mask is " + std::to_string(mask.width) + "x" + std::to_string(mask.height) +
                    " but the images are " + std::to_string(reference.width) + "x" +
                    std::to_string(reference.height));
    std::vector<uint8_t> selected(mask.pixelCount());
    for (size_t p = 0; p < selected.size(); ++p) selected[p] = mask.pixels[p * mask.channels()] > 0.5f;
    return selected;
}

int bandHeight(int height) {
    return std::max(16, height / std::max(1, threadCount() * 3));
}

}  // namespace

std::vector<float> ssimWindow() {
    // scipy.ndimage.gaussian_filter: weights exp(-x^2 / (2 sigma^2)) normalised in double.
    double weights[kSsimTaps], sum = 0.0;
    for (int k = 0; k < kSsimTaps; ++k) {
        const double x = k - kSsimRadius;
        weights[k] = std::exp(-0.5 * x * x / (kSigma * kSigma));
        sum += weights[k];
    }
    std::vector<float> window(kSsimTaps);
    for (int k = 0; k < kSsimTaps; ++k) window[k] = float(weights[k] / sum);
    return window;
}

SsimResult structuralSimilarity(const Image& reference, const Image& test, double dataRange,
                                const Image* mask, bool wantMap) {
    requireSameShape(reference, test);
    const int width = reference.width, height = reference.height, channels = reference.channels();
    if (width < kSsimTaps || height < kSsimTaps)
        throw Error("the images are " + std::to_string(width) + "x" + std::to_string(height) +
                    ", smaller than the 11x11 SSIM window");
    if (!(dataRange > 0.0) || !std::isfinite(dataRange)) throw Error("the SSIM data range must be positive");

    const std::vector<float> window = ssimWindow();
    std::vector<uint8_t> selected;
    if (mask) selected = selectedPixels(*mask, reference);
    const bool needMaps = wantMap || mask;
    std::vector<float> maps(needMaps ? size_t(channels) * reference.pixelCount() : 0);

    // Shift each channel by its mid-range (estimated from every 4th pixel of every 4th row of both images,
    // cheap next to SSIM itself): the smallest
    // worst-case |sample - offset|, which bounds the float32 cancellation in E[x^2] - mean^2, and exact for
    // flat images.
    std::vector<float> rowMin(size_t(height) * channels, 0.0f), rowMax(size_t(height) * channels, 0.0f);
    parallelFor(0, (height + 3) / 4, 0, [&](int64_t first, int64_t last) {
        for (int64_t i = first; i < last; ++i) {
            const int y = int(i * 4);
            for (const Image* image : {&reference, &test}) {
                const float* row = image->row(y);
                for (int c = 0; c < channels; ++c) {
                    float low = row[c], high = row[c];
                    for (int x = 4; x < width; x += 4) {
                        low = std::min(low, row[x * channels + c]);
                        high = std::max(high, row[x * channels + c]);
                    }
                    float& rowLow = rowMin[size_t(y) * channels + c];
                    float& rowHigh = rowMax[size_t(y) * channels + c];
                    rowLow = image == &reference ? low : std::min(rowLow, low);
                    rowHigh = image == &reference ? high : std::max(rowHigh, high);
                }
            }
        }
    });
    std::vector<float> offsets(channels, 0.0f);
    for (int c = 0; c < channels; ++c) {
        float low = rowMin[c], high = rowMax[c];
        for (int y = 0; y < height; y += 4) {
            low = std::min(low, rowMin[size_t(y) * channels + c]);
            high = std::max(high, rowMax[size_t(y) * channels + c]);
        }
        offsets[c] = 0.5f * (low + high);
    }

    // Work items: bands of rows x tiles of columns. Tiles are fixed (independent of the thread count),
    // and every tile writes its own row sums, added up below in a fixed order: results do not depend on
    // the number of threads.
    const int rowsPerBand = bandHeight(height);
    const int bands = (height + rowsPerBand - 1) / rowsPerBand;
    const int tiles = (width + kSsimTileWidth - 1) / kSsimTileWidth;
    std::vector<double> rowSums(size_t(tiles) * channels * height, 0.0);
    parallelFor(0, int64_t(bands) * tiles, 1, [&](int64_t first, int64_t last) {
        thread_local std::vector<float> scratch;
        for (int64_t job = first; job < last; ++job) {
            const int band = int(job / tiles), tileIndex = int(job % tiles);
            SsimTile tile;
            tile.reference = reference.pixels.data();
            tile.test = test.pixels.data();
            tile.width = width;
            tile.height = height;
            tile.channels = channels;
            tile.offsets = offsets.data();
            tile.c1 = float((kK1 * dataRange) * (kK1 * dataRange));
            tile.c2 = float((kK2 * dataRange) * (kK2 * dataRange));
            tile.weights = window.data();
            tile.rowBegin = band * rowsPerBand;
            tile.rowEnd = std::min(height, tile.rowBegin + rowsPerBand);
            tile.columnBegin = tileIndex * kSsimTileWidth;
            tile.columnEnd = std::min(width, tile.columnBegin + kSsimTileWidth);
            tile.maps = needMaps ? maps.data() : nullptr;
            tile.rowSums = rowSums.data() + size_t(tileIndex) * channels * height;
            scratch.resize(ssimScratchFloats(channels, tile.columnEnd - tile.columnBegin));
            tile.scratch = scratch.data();
            DEJAG_SIMD_CALL(ssimTile, tile);
        }
    });

    SsimResult result;
    result.perChannel.assign(channels, 0.0);
    const int r = kSsimRadius;
    if (!mask) {
        result.scoredPixels = int64_t(width - 2 * r) * (height - 2 * r);
        for (int c = 0; c < channels; ++c) {
            double sum = 0.0;
            for (int y = r; y < height - r; ++y)
                for (int t = 0; t < tiles; ++t) sum += rowSums[(size_t(t) * channels + c) * height + y];
            result.perChannel[c] = sum / double(result.scoredPixels);
        }
    } else {
        for (int y = r; y < height - r; ++y)
            for (int x = r; x < width - r; ++x) result.scoredPixels += selected[size_t(y) * width + x];
        if (result.scoredPixels == 0)
            throw Error("the mask selects no pixel at least 5 pixels inside the image");
        for (int c = 0; c < channels; ++c) {
            const float* map = maps.data() + size_t(c) * reference.pixelCount();
            double sum = 0.0;
            for (int y = r; y < height - r; ++y)
                for (int x = r; x < width - r; ++x)
                    if (selected[size_t(y) * width + x]) sum += map[size_t(y) * width + x];
            result.perChannel[c] = sum / double(result.scoredPixels);
        }
    }
    for (double channelSsim : result.perChannel) result.mean += channelSsim;
    result.mean /= channels;

    if (wantMap) {
        result.map.assign(reference.pixelCount(), 0.0f);
        for (int c = 0; c < channels; ++c) {
            const float* map = maps.data() + size_t(c) * reference.pixelCount();
            for (size_t p = 0; p < result.map.size(); ++p) result.map[p] += map[p];
        }
        for (float& value : result.map) value /= float(channels);
    }
    return result;
}

ImageMetrics compareImages(const Image& reference, const Image& test, const MetricOptions& options) {
    requireSameShape(reference, test);
    ImageMetrics metrics;
    metrics.valueScale = valueScale(reference.storage);
    metrics.dataRange = options.dataRange > 0.0 ? options.dataRange : metrics.valueScale;
    if (!std::isfinite(metrics.dataRange)) throw Error("the data range must be a finite positive number");
    // Samples are compared in memory (8-bit as [0, 1]); every metric but MSE/RMSE is scale-invariant.
    const double rangeInMemory = metrics.dataRange / metrics.valueScale;

    const int width = reference.width, height = reference.height, channels = reference.channels();
    std::vector<uint8_t> selected;
    if (options.mask) selected = selectedPixels(*options.mask, reference);

    std::vector<double> rowError(height, 0.0), rowEnergy(height, 0.0);
    std::vector<int64_t> rowPixels(height, width);
    parallelFor(0, height, std::max(1, bandHeight(height) / 4), [&](int64_t first, int64_t last) {
        for (int64_t y = first; y < last; ++y) {
            const float* r = reference.row(int(y));
            const float* t = test.row(int(y));
            if (!options.mask) {
                DEJAG_SIMD_CALL(sumSquaredError, r, t, int64_t(width) * channels, &rowError[y],
                                &rowEnergy[y]);
                continue;
            }
            double error = 0.0, energy = 0.0;
            int64_t count = 0;
            for (int x = 0; x < width; ++x) {
                if (!selected[size_t(y) * width + x]) continue;
                ++count;
                for (int c = 0; c < channels; ++c) {
                    const double d = double(t[x * channels + c]) - double(r[x * channels + c]);
                    error += d * d;
                    energy += double(r[x * channels + c]) * r[x * channels + c];
                }
            }
            rowError[y] = error;
            rowEnergy[y] = energy;
            rowPixels[y] = count;
        }
    });
    double error = 0.0, energy = 0.0;
    for (int y = 0; y < height; ++y) {
        error += rowError[y];
        energy += rowEnergy[y];
        metrics.scoredPixels += rowPixels[y];
    }
    if (metrics.scoredPixels == 0) throw Error("the mask selects no pixel");
    const double samples = double(metrics.scoredPixels) * channels;
    const double mseInMemory = error / samples;
    metrics.mse = mseInMemory * metrics.valueScale * metrics.valueScale;
    metrics.rmse = std::sqrt(metrics.mse);
    const double infinity = std::numeric_limits<double>::infinity();
    metrics.psnr =
        mseInMemory > 0.0 ? 10.0 * std::log10(rangeInMemory * rangeInMemory / mseInMemory) : infinity;
    metrics.snr = mseInMemory > 0.0 ? 10.0 * std::log10((energy / samples) / mseInMemory) : infinity;

    SsimResult ssim = structuralSimilarity(reference, test, rangeInMemory, options.mask, options.wantSsimMap);
    metrics.ssim = ssim.mean;
    metrics.ssimPerChannel = std::move(ssim.perChannel);
    metrics.ssimScoredPixels = ssim.scoredPixels;
    metrics.ssimMap = std::move(ssim.map);
    return metrics;
}

void writeSsimMapPng(const std::string& path, const std::vector<float>& map, int width, int height) {
    if (map.size() != size_t(width) * height)
        throw Error("SSIM map does not match " + std::to_string(width) + "x" + std::to_string(height));
    Image image(width, height, {"R", "G", "B"}, PixelType::UInt8);
    for (size_t p = 0; p < map.size(); ++p) {
        const Rgb colour = viridis(map[p]);
        image.pixels[p * 3 + 0] = colour.r;
        image.pixels[p * 3 + 1] = colour.g;
        image.pixels[p * 3 + 2] = colour.b;
    }
    writeImage(path, image);
}

void FlickerMeter::add(const std::vector<float>& output, const std::vector<float>& truth) {
    if (output.size() != truth.size()) throw Error("flicker: the output and the truth differ in size");
    if (!previous_.empty()) {
        if (previous_.size() != output.size()) throw Error("flicker: the frames differ in size");
        double s = 0;
        for (size_t i = 0; i < output.size(); ++i)
            s += std::abs(double(output[i] - previous_[i]) - double(truth[i] - previousTruth_[i]));
        sum_ += s / double(std::max<size_t>(output.size(), 1)), ++pairs_;
    }
    previous_ = output, previousTruth_ = truth;
}

}  // namespace dejag
