// SIMD kernels for data/metrics.cpp; compiled once per SIMD level (see data/metrics_kernels.h).
#include "data/metrics_kernels.h"

#include "base/simd_vector.h"

namespace dejag::DEJAG_SIMD_NAMESPACE {
namespace {

constexpr int kMoments = 5;  // x, y, xx, yy, xy

inline int reflect(int i, int n) {
    return i < 0 ? -i - 1 : (i >= n ? 2 * n - i - 1 : i);
}

// Horizontal 11-tap filter of the five moment rows at columns [j, j + lanes of V).
template <class V>
inline void filterRowAt(int j, const float* const padded[kMoments], float* const out[kMoments],
                        const float* weights) {
    V sum[kMoments];
    for (int m = 0; m < kMoments; ++m) sum[m] = splat<V>(0.0f);
    for (int k = 0; k < kSsimTaps; ++k) {
        const V w = splat<V>(weights[k]);
        for (int m = 0; m < kMoments; ++m) sum[m] += w * loadu<V>(padded[m] + j + k);
    }
    for (int m = 0; m < kMoments; ++m) storeu(out[m] + j, sum[m]);
}

// Vertical 11-tap filter of the ring rows, then the SSIM of spec/metrics.md, at columns [j, j + lanes).
template <class V>
inline void ssimAt(int j, const float* const rows[kMoments][kSsimTaps], const SsimBand& band,
                   float* ssimRow) {
    V mu[kMoments];
    for (int m = 0; m < kMoments; ++m) mu[m] = splat<V>(0.0f);
    for (int k = 0; k < kSsimTaps; ++k) {
        const V w = splat<V>(band.weights[k]);
        for (int m = 0; m < kMoments; ++m) mu[m] += w * loadu<V>(rows[m][k] + j);
    }
    // Moments of the shifted samples: variances and covariance are shift-invariant.
    const V varianceX = mu[2] - mu[0] * mu[0];
    const V varianceY = mu[3] - mu[1] * mu[1];
    const V covariance = mu[4] - mu[0] * mu[1];
    const V meanX = mu[0] + band.offset;
    const V meanY = mu[1] + band.offset;
    const V luminanceNum = 2.0f * meanX * meanY + band.c1;
    const V structureNum = 2.0f * covariance + band.c2;
    const V luminanceDen = meanX * meanX + meanY * meanY + band.c1;
    const V structureDen = varianceX + varianceY + band.c2;
    V ssim = (luminanceNum * structureNum) / (luminanceDen * structureDen);
    // SSIM <= 1 exactly; float rounding (FMA contraction) can overshoot by ~1e-7 on identical inputs.
    ssim = ssim > 1.0f ? splat<V>(1.0f) : ssim;
    storeu(ssimRow + j, ssim);
}

template <class V>
inline V accumulateLoad(V acc, const float* p) {
    return acc + loadu<V>(p);
}

}  // namespace

void ssimBand(const SsimBand& band) {
    const int width = band.width, height = band.height, channels = band.channels;
    const int paddedWidth = width + 2 * kSsimRadius;
    float* padded[kMoments];
    for (int m = 0; m < kMoments; ++m) padded[m] = band.scratch + size_t(m) * paddedWidth;
    float* ring = band.scratch + size_t(kMoments) * paddedWidth;  // [moment][tap slot][W]
    float* rowBuffer = ring + size_t(kMoments) * kSsimTaps * width;
    auto ringRow = [&](int moment, int inputRow) {
        int slot = ((inputRow % kSsimTaps) + kSsimTaps) % kSsimTaps;
        return ring + (size_t(moment) * kSsimTaps + slot) * width;
    };
    const int vectorEnd = width - width % kFloatLanes;

    for (int inputRow = band.rowBegin - kSsimRadius; inputRow < band.rowEnd + kSsimRadius; ++inputRow) {
        const int sourceRow = reflect(inputRow, height);
        const float* x = band.reference + size_t(sourceRow) * width * channels + band.channel;
        const float* y = band.test + size_t(sourceRow) * width * channels + band.channel;
        // Gather the channel (strided), reflect the borders, then form the products vectorised.
        float* px = padded[0] + kSsimRadius;
        float* py = padded[1] + kSsimRadius;
        for (int j = 0; j < width; ++j) {
            px[j] = x[size_t(j) * channels];
            py[j] = y[size_t(j) * channels];
        }
        for (int j = 1; j <= kSsimRadius; ++j) {
            px[-j] = px[j - 1];
            py[-j] = py[j - 1];
            px[width - 1 + j] = px[width - j];
            py[width - 1 + j] = py[width - j];
        }
        {
            const VFloat offset = splat<VFloat>(band.offset);
            int j = 0;
            for (; j + kFloatLanes <= paddedWidth; j += kFloatLanes) {
                const VFloat xs = loadu<VFloat>(padded[0] + j) - offset;
                const VFloat ys = loadu<VFloat>(padded[1] + j) - offset;
                storeu(padded[0] + j, xs);
                storeu(padded[1] + j, ys);
                storeu(padded[2] + j, xs * xs);
                storeu(padded[3] + j, ys * ys);
                storeu(padded[4] + j, xs * ys);
            }
            for (; j < paddedWidth; ++j) {
                const float xs = padded[0][j] - band.offset, ys = padded[1][j] - band.offset;
                padded[0][j] = xs;
                padded[1][j] = ys;
                padded[2][j] = xs * xs;
                padded[3][j] = ys * ys;
                padded[4][j] = xs * ys;
            }
        }
        float* out[kMoments];
        for (int m = 0; m < kMoments; ++m) out[m] = ringRow(m, inputRow);
        int j = 0;
        for (; j < vectorEnd; j += kFloatLanes) filterRowAt<VFloat>(j, padded, out, band.weights);
        for (; j < width; ++j) filterRowAt<float>(j, padded, out, band.weights);

        const int outputRow = inputRow - kSsimRadius;  // its window is complete once inputRow is filtered
        if (outputRow < band.rowBegin) continue;
        const float* rows[kMoments][kSsimTaps];
        for (int m = 0; m < kMoments; ++m)
            for (int k = 0; k < kSsimTaps; ++k) rows[m][k] = ringRow(m, outputRow - kSsimRadius + k);
        float* ssimRow = band.map ? band.map + size_t(outputRow) * width : rowBuffer;
        for (j = 0; j < vectorEnd; j += kFloatLanes) ssimAt<VFloat>(j, rows, band, ssimRow);
        for (; j < width; ++j) ssimAt<float>(j, rows, band, ssimRow);

        if (band.rowSums) {
            // Sum over the columns scikit-image keeps (it crops `radius` pixels on every side).
            const int begin = kSsimRadius, end = width - kSsimRadius;
            VFloat vectorSum = splat<VFloat>(0.0f);
            int c = begin;
            for (; c + kFloatLanes <= end; c += kFloatLanes)
                vectorSum = accumulateLoad(vectorSum, ssimRow + c);
            double sum = horizontalSum(vectorSum);
            for (; c < end; ++c) sum += ssimRow[c];
            band.rowSums[outputRow] = sum;
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
