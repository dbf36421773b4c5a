// dejag/nn: losses, each value and gradient side by side.
//
// Every backward ADDS scale * dLoss/dprediction into dpred (scale carries the weight of the term in a
// combined loss such as 0.84 (1 - SSIM) + 0.16 L1, and the upstream gradient, usually 1).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace dejag::nn {

// Mean absolute error over n values; d/dp |p - t| = sign(p - t), 0 at p == t (as PyTorch).
template <class T>
double l1Loss(const T* pred, const T* target, int64_t n);
template <class T>
void l1LossBackward(T* dpred, const T* pred, const T* target, int64_t n, double scale);

// Mean squared error over n values.
template <class T>
double mseLoss(const T* pred, const T* target, int64_t n);
template <class T>
void mseLossBackward(T* dpred, const T* pred, const T* target, int64_t n, double scale);

// 1 - SSIM with the constants and window of docs/metrics.md (11x11 Gaussian, sigma 1.5, K1 0.01,
// K2 0.03, population covariance), over the valid region of every (N, C) plane (the pixels whose window
// lies inside the plane: the same pixels scikit-image averages), mean over planes and pixels.
// Internals are computed in double: stable on flat patches (zero variance; C1 and C2 keep every
// denominator >= C1 C2 > 0) and on values far outside [0, 1].
struct SsimLossDesc {
    int64_t batch = 1, channels = 1, height = 11, width = 11;
    double dataRange = 1.0;
    void validate() const;  // planes must be at least 11x11
};
template <class T>
double ssimLoss(const T* pred, const T* target, const SsimLossDesc& d);  // (N, C, H, W) each
template <class T>
void ssimLossBackward(T* dpred, const T* pred, const T* target, const SsimLossDesc& d, double scale);

// Harm: how much worse than its input the prediction is, per sample — the mean over the batch of
//   max(0, MSE(pred_n, target_n) - MSE(input_n, target_n)) / (MSE(input_n, target_n) + harmEpsilon),
// each MSE over sample n's channels and pixels. Zero wherever the prediction is at least as close to the
// target as the input was; otherwise its relative excess error (about 0.23 per dB lost, for small
// losses), so a network trained with it steps back toward its input where it cannot help
// (docs/train.md, "Never harm"). At the hinge (equal errors) the gradient is that of the zero side.
inline constexpr double kHarmEpsilon = 1e-4;  // an input error of 40 dB PSNR
template <class T>
double harmLoss(const T* pred, const T* input, const T* target, int64_t batch, int64_t perSample);
template <class T>
void harmLossBackward(T* dpred, const T* pred, const T* input, const T* target, int64_t batch,
                      int64_t perSample, double scale);
// Harm by tiles ("harmN"): the same hinge on each N x N block of each sample (all its channels; the last
// blocks of a row or column as wide as what is left), averaged over every block of the batch. A network
// that helps most of a patch cannot buy harm in one corner of it with that gain: local harm, a texture
// blurred beside an edge made smooth, is paid where it happens.
template <class T>
double harmTilesLoss(const T* pred, const T* input, const T* target, const SsimLossDesc& d, int tile);
template <class T>
void harmTilesLossBackward(T* dpred, const T* pred, const T* input, const T* target, const SsimLossDesc& d,
                           int tile, double scale);

// Harm on masked pixels ("texharm": the mask marks a patch's texture pixels, docs/train.md "Never harm"):
// per sample, the hinge of harmLoss on the weighted mean squared errors
//   E = sum over pixels of m * (sum over channels of (v - target)^2) / (channels * sum of m),
// mask m (N, 1, H, W) in [0, 1]; a sample whose mask is empty adds 0. Mean over the batch. It asks the
// network never to make a patch's texture worse than its input even where the patch as a whole gains.
template <class T>
double maskedHarmLoss(const T* pred, const T* input, const T* target, const T* mask, const SsimLossDesc& d);
template <class T>
void maskedHarmLossBackward(T* dpred, const T* pred, const T* input, const T* target, const T* mask,
                            const SsimLossDesc& d, double scale);

// A weighted sum of the losses above, e.g. "ssim" or "0.84*ssim+0.16*l1" (or "...+0.5*harm",
// "...+0.5*harm16" or "...+0.5*texharm", which need the input the prediction was made from; texharm also
// a mask).
enum class LossKind { Ssim, L1, Mse, Harm, MaskedHarm };
struct LossTerm {
    LossKind kind = LossKind::Ssim;
    double weight = 1.0;
    int tile = 0;  // harm: per N x N block ("harmN"; 0: per sample)
};
struct CompositeLoss {
    std::vector<LossTerm> terms;
    static CompositeLoss parse(const std::string& text);  // throws dejag::Error on a bad spec
    std::string describe() const;
    bool needsInput() const;  // a harm term: evaluate() needs `input`
    bool needsMask() const;   // a texharm term: evaluate() needs `mask`
    // Value of the weighted sum; if dpred is non-null, adds its gradient (times scale) into dpred.
    // `input` (the prediction's shape) is what the network was given; only a harm term reads it, and
    // throws dejag::Error if it is null. `mask` (N, 1, H, W): only texharm reads it, likewise.
    template <class T>
    double evaluate(T* dpred, const T* pred, const T* target, const SsimLossDesc& shape, double scale = 1.0,
                    const T* input = nullptr, const T* mask = nullptr) const;
};

}  // namespace dejag::nn
