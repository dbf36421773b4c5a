// SIMD kernels for data/metrics.cpp; compiled once per SIMD level (see data/metrics_kernels.h).
#include "data/metrics_kernels.h"

#include <algorithm>

#include "base/simd_vector.h"

namespace dejag::DEJAG_SIMD_NAMESPACE {
namespace {

constexpr int kMoments = 5;  // x, y, xx, yy, xy

inline int reflect(int i, int n) {
    return i < 0 ? -i - 1 : (i >= n ? 2 * n - i - 1 : i);
}

// The window broadcast once per tile, in registers for the filter loops (the output stores could alias
// a weights pointer, so loading weights inside the loops would reload them every time).
template <class V>
struct Window {
    V taps[kSsimTaps];
    explicit Window(const float* weights) {
        for (int k = 0; k < kSsimTaps; ++k) taps[k] = splat<V>(weights[k]);
    }
};

// 11-tap filter of `rows[k] + j` (vertical: one row per tap) or `row + j + k` (horizontal).
template <class V>
inline V filterTaps(const float* const rows[kSsimTaps], int j, const Window<V>& w) {
    V sum = w.taps[0] * loadu<V>(rows[0] + j);
#pragma GCC unroll 11
    for (int k = 1; k < kSsimTaps; ++k) sum += w.taps[k] * loadu<V>(rows[k] + j);
    return sum;
}

template <class V>
inline V filterTaps(const float* row, int j, const Window<V>& w) {
    V sum = w.taps[0] * loadu<V>(row + j);
#pragma GCC unroll 11
    for (int k = 1; k < kSsimTaps; ++k) sum += w.taps[k] * loadu<V>(row + j + k);
    return sum;
}

// SSIM of docs/metrics.md from the five filtered moments (of samples shifted by -offset).
template <class V>
inline V ssimFromMoments(const float* moments, int stride, int j, float offset, float c1, float c2) {
    const V meanXs = loadu<V>(moments + j), meanYs = loadu<V>(moments + stride + j);
    const V varianceX = loadu<V>(moments + 2 * stride + j) - meanXs * meanXs;
    const V varianceY = loadu<V>(moments + 3 * stride + j) - meanYs * meanYs;
    const V covariance = loadu<V>(moments + 4 * stride + j) - meanXs * meanYs;
    const V meanX = meanXs + offset, meanY = meanYs + offset;
    const V ssim = ((2.0f * meanX * meanY + c1) * (2.0f * covariance + c2)) /
                   ((meanX * meanX + meanY * meanY + c1) * (varianceX + varianceY + c2));
    // SSIM <= 1 exactly; float rounding (FMA contraction) can overshoot by ~1e-7 on identical inputs.
    return ssim > 1.0f ? splat<V>(1.0f) : ssim;
}

// De-interleaves columns [first, first + count) of one row of both images into per-channel rows
// (x of channel c at out + c * channelStride, y at out + c * channelStride + yOffset), reflecting
// columns outside the image. The interior is a straight strided copy, specialised for 1 and 3 channels.
template <int kChannels>
inline void gatherInterior(const float* x, const float* y, int channels, int first, int last, float* out,
                           size_t channelStride, size_t yOffset, int outBase) {
    const int c = kChannels > 0 ? kChannels : channels;
    for (int column = first; column < last; ++column) {
        const float* xs = x + size_t(column) * c;
        const float* ys = y + size_t(column) * c;
        float* o = out + (column - outBase);
        for (int k = 0; k < c; ++k) {
            o[k * channelStride] = xs[k];
            o[k * channelStride + yOffset] = ys[k];
        }
    }
}

inline void gatherRow(const float* x, const float* y, int width, int channels, int firstColumn, int count,
                      float* out, size_t channelStride, size_t yOffset) {
    const int interiorBegin = std::max(firstColumn, 0), interiorEnd = std::min(firstColumn + count, width);
    if (channels == 3)
        gatherInterior<3>(x, y, channels, interiorBegin, interiorEnd, out, channelStride, yOffset,
                          firstColumn);
    else if (channels == 1)
        gatherInterior<1>(x, y, channels, interiorBegin, interiorEnd, out, channelStride, yOffset,
                          firstColumn);
    else
        gatherInterior<0>(x, y, channels, interiorBegin, interiorEnd, out, channelStride, yOffset,
                          firstColumn);
    for (int j = 0; j < count; ++j) {
        const int column = firstColumn + j;
        if (column >= interiorBegin && column < interiorEnd) continue;
        const size_t source = size_t(reflect(column, width)) * channels;
        for (int k = 0; k < channels; ++k) {
            out[k * channelStride + j] = x[source + k];
            out[k * channelStride + yOffset + j] = y[source + k];
        }
    }
}

}  // namespace

void ssimTile(const SsimTile& tile) {
    const int width = tile.width, height = tile.height, channels = tile.channels;
    const int x0 = tile.columnBegin, tileWidth = tile.columnEnd - tile.columnBegin;
    const int paddedWidth = tileWidth + 2 * kSsimRadius;
    const int vectorEnd = tileWidth - tileWidth % kFloatLanes;
    const Window<VFloat> window(tile.weights);
    const Window<float> scalarWindow(tile.weights);
    float* padded = tile.scratch;                                      // [C][moment][paddedWidth]
    float* ring = padded + size_t(channels) * kMoments * paddedWidth;  // [C][moment][slot][tileWidth]
    float* moments = ring + size_t(channels) * kMoments * kSsimTaps * tileWidth;  // [moment][tileWidth]
    float* rowBuffer = moments + size_t(kMoments) * tileWidth;                    // [tileWidth]
    auto paddedRow = [&](int c, int m) { return padded + (size_t(c) * kMoments + m) * paddedWidth; };
    auto ringRow = [&](int c, int m, int inputRow) {
        const int slot = ((inputRow % kSsimTaps) + kSsimTaps) % kSsimTaps;
        return ring + ((size_t(c) * kMoments + m) * kSsimTaps + slot) * tileWidth;
    };

    for (int inputRow = tile.rowBegin - kSsimRadius; inputRow < tile.rowEnd + kSsimRadius; ++inputRow) {
        // Gather every channel of the tile's columns plus the halo (reflected at the image borders).
        const int sourceRow = reflect(inputRow, height);
        const float* x = tile.reference + size_t(sourceRow) * width * channels;
        const float* y = tile.test + size_t(sourceRow) * width * channels;
        gatherRow(x, y, width, channels, x0 - kSsimRadius, paddedWidth, paddedRow(0, 0),
                  size_t(kMoments) * paddedWidth, paddedWidth);
        for (int c = 0; c < channels; ++c) {
            float* xs = paddedRow(c, 0);
            float* ys = paddedRow(c, 1);
            float* xx = paddedRow(c, 2);
            float* yy = paddedRow(c, 3);
            float* xy = paddedRow(c, 4);
            const float offset = tile.offsets[c];
            int j = 0;
            for (; j + kFloatLanes <= paddedWidth; j += kFloatLanes) {
                const VFloat a = loadu<VFloat>(xs + j) - offset, b = loadu<VFloat>(ys + j) - offset;
                storeu(xs + j, a);
                storeu(ys + j, b);
                storeu(xx + j, a * a);
                storeu(yy + j, b * b);
                storeu(xy + j, a * b);
            }
            for (; j < paddedWidth; ++j) {
                const float a = xs[j] - offset, b = ys[j] - offset;
                xs[j] = a;
                ys[j] = b;
                xx[j] = a * a;
                yy[j] = b * b;
                xy[j] = a * b;
            }
            for (int m = 0; m < kMoments; ++m) {
                const float* in = paddedRow(c, m);
                float* out = ringRow(c, m, inputRow);
                for (j = 0; j < vectorEnd; j += kFloatLanes)
                    storeu(out + j, filterTaps<VFloat>(in, j, window));
                for (; j < tileWidth; ++j) out[j] = filterTaps<float>(in, j, scalarWindow);
            }
        }

        const int outputRow = inputRow - kSsimRadius;  // its window is complete once inputRow is filtered
        if (outputRow < tile.rowBegin) continue;
        for (int c = 0; c < channels; ++c) {
            for (int m = 0; m < kMoments; ++m) {
                const float* rows[kSsimTaps];
                for (int k = 0; k < kSsimTaps; ++k) rows[k] = ringRow(c, m, outputRow - kSsimRadius + k);
                float* out = moments + size_t(m) * tileWidth;
                int j = 0;
                for (; j < vectorEnd; j += kFloatLanes) storeu(out + j, filterTaps<VFloat>(rows, j, window));
                for (; j < tileWidth; ++j) out[j] = filterTaps<float>(rows, j, scalarWindow);
            }
            float* ssimRow =
                tile.maps ? tile.maps + (size_t(c) * height + outputRow) * width + x0 : rowBuffer;
            const float offset = tile.offsets[c];
            int j = 0;
            for (; j < vectorEnd; j += kFloatLanes)
                storeu(ssimRow + j, ssimFromMoments<VFloat>(moments, tileWidth, j, offset, tile.c1, tile.c2));
            for (; j < tileWidth; ++j)
                ssimRow[j] = ssimFromMoments<float>(moments, tileWidth, j, offset, tile.c1, tile.c2);

            if (tile.rowSums) {
                // Sum over the columns scikit-image keeps (it crops `radius` pixels on every side).
                const int begin = std::max(x0, kSsimRadius) - x0;
                const int end = std::min(tile.columnEnd, width - kSsimRadius) - x0;
                VFloat vectorSum = splat<VFloat>(0.0f);
                int k = begin;
                for (; k + kFloatLanes <= end; k += kFloatLanes) vectorSum += loadu<VFloat>(ssimRow + k);
                double sum = horizontalSum(vectorSum);
                for (; k < end; ++k) sum += ssimRow[k];
                tile.rowSums[size_t(c) * height + outputRow] = sum;
            }
        }
    }
}

void sumSquaredError(const float* reference, const float* test, int64_t n, double* squaredError,
                     double* referenceEnergy) {
    VFloat error = splat<VFloat>(0.0f), energy = splat<VFloat>(0.0f);
    int64_t i = 0;
    for (; i + kFloatLanes <= n; i += kFloatLanes) {
        const VFloat r = loadu<VFloat>(reference + i);
        const VFloat d = loadu<VFloat>(test + i) - r;
        error += d * d;
        energy += r * r;
    }
    double errorSum = horizontalSum(error), energySum = horizontalSum(energy);
    for (; i < n; ++i) {
        const double d = double(test[i]) - double(reference[i]);
        errorSum += d * d;
        energySum += double(reference[i]) * reference[i];
    }
    *squaredError = errorSum;
    *referenceEnergy = energySum;
}

}  // namespace dejag::DEJAG_SIMD_NAMESPACE
