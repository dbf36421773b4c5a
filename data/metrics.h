// dejag/data: image quality metrics as the anti-aliasing literature computes them (docs/metrics.md).
//
// All metrics compare a test image X against a reference R (the supersampled truth):
//   MSE  = mean over pixels and channels of (X - R)^2, on the reference's value scale
//          (0-255 for 8-bit, 0-65535 for 16-bit, raw values for half/float);
//   RMSE = sqrt(MSE);  PSNR = 10 log10(L^2 / MSE), L the data range;
//   SNR  = 10 log10(mean(R^2) / MSE);
//   SSIM = Wang et al. 2004 with an 11x11 Gaussian window (sigma 1.5), K1 = 0.01, K2 = 0.03, population
//          covariance, averaged over the pixels at least 5 pixels from every border (as scikit-image
//          crops), and for colour the mean of the per-channel SSIMs.
// Identical images give MSE 0 and PSNR/SNR = +infinity.
// A mask restricts every metric to the pixels whose mask value is above 0.5 (for SSIM: those pixels of
// the per-pixel SSIM map that lie inside the cropped region).
#pragma once

#include <cstdint>
#include <vector>

#include "data/image.h"

namespace dejag {

struct MetricOptions {
    // Data range L on the reported scale; 0 takes it from the reference's pixel type (255 for 8-bit,
    // 65535 for 16-bit, 1 for half and float).
    double dataRange = 0.0;
    const Image* mask = nullptr;  // same width and height; its first channel selects pixels (> 0.5)
    bool wantSsimMap = false;
};

struct ImageMetrics {
    double valueScale = 1.0;  // in-memory samples times this = reported scale (255 for 8-bit)
    double dataRange = 1.0;   // L on the reported scale
    double mse = 0.0, rmse = 0.0, psnr = 0.0, snr = 0.0, ssim = 0.0;
    std::vector<double> ssimPerChannel;
    int64_t scoredPixels = 0;      // pixels counted by MSE/PSNR/SNR
    int64_t ssimScoredPixels = 0;  // pixels counted by SSIM
    std::vector<float> ssimMap;    // (H, W) per-pixel SSIM, mean over channels, if asked for
};

// Throws dejag::Error if the images differ in size or channel count, the mask in size, or the image is
// smaller than the SSIM window (11x11), or the mask selects no pixel.
ImageMetrics compareImages(const Image& reference, const Image& test, const MetricOptions& options = {});

// The normalised Gaussian SSIM window.
std::vector<float> ssimWindow();

// Lower level: SSIM of samples already on a common scale with data range `dataRange`.
struct SsimResult {
    double mean = 0.0;
    std::vector<double> perChannel;
    int64_t scoredPixels = 0;
    std::vector<float> map;  // (H, W) mean over channels, if wantMap
};
SsimResult structuralSimilarity(const Image& reference, const Image& test, double dataRange,
                                const Image* mask = nullptr, bool wantMap = false);

// Writes an SSIM map as a colour-mapped PNG (viridis; 1 = yellow, 0 or below = dark purple).
void writeSsimMapPng(const std::string& path, const std::vector<float>& map, int width, int height);

// Flicker of a sequence against its truth (docs/metrics.md): the mean over pixels and channels of
// |(X_t - X_t-1) - (R_t - R_t-1)|, averaged over the pairs of frames given one after the other (on the
// values given: 8-bit sRGB scaled to [0, 1] in dejag's benchmarks).
class FlickerMeter {
  public:
    void add(const std::vector<float>& output, const std::vector<float>& truth);
    double value() const { return pairs_ ? sum_ / pairs_ : 0.0; }
    int pairs() const { return pairs_; }

  private:
    std::vector<float> previous_, previousTruth_;
    double sum_ = 0;
    int pairs_ = 0;
};

}  // namespace dejag
