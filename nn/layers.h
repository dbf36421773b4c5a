// dejag/nn: the layers, forward and backward side by side (the reference kernels).
//
// Conventions (after llm.c):
// - Arguments go outputs, saved values, inputs, weights, then the descriptor of sizes.
// - Every buffer's layout is in a comment: (N, C, H, W) activations, PyTorch weight layouts
//   (Conv2D (Cout, Cin, kh, kw); ConvTranspose2D (Cin, Cout, kh, kw)).
// - BACKWARD ACCUMULATES: every backward adds (+=) into its gradient buffers (dinput, dweight, dbias),
//   so a tensor used twice (a skip connection) collects both contributions; zero them before a step.
//   A null gradient pointer skips that gradient.
// - Kernels are templates instantiated for float (training, inference) and double (gradient checks).
// - Work is split over output planes (or gradient slices) across the thread pool; each element is
//   computed by one thread in a fixed order, so results do not depend on the thread count.
// These are the oracle the fast kernels of nn/ are tested against; keep them simple and correct.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace dejag::nn {

// ---- Conv2D ---------------------------------------------------------------------------------------
struct Conv2dDesc {
    int64_t batch = 1, inChannels = 1, inHeight = 1, inWidth = 1;
    int64_t outChannels = 1, kernelHeight = 3, kernelWidth = 3;
    int strideH = 1, strideW = 1;
    int padTop = 0, padBottom = 0, padLeft = 0, padRight = 0;
    int dilationH = 1, dilationW = 1;
    bool bias = true;

    int64_t outHeight() const;
    int64_t outWidth() const;
    int64_t weightCount() const { return outChannels * inChannels * kernelHeight * kernelWidth; }
    int64_t macs() const {
        return batch * outChannels * outHeight() * outWidth() * inChannels * kernelHeight * kernelWidth;
    }
    void validate() const;  // throws dejag::Error naming the bad field
    // Keras/TensorFlow 'same' padding: output = ceil(input / stride), the extra pixel after.
    void setSamePadding();
};

template <class T>
void conv2dForward(T* out,           // (N, Cout, OH, OW)
                   const T* in,      // (N, Cin, H, W)
                   const T* weight,  // (Cout, Cin, kh, kw)
                   const T* bias,    // (Cout) or null
                   const Conv2dDesc& d);
template <class T>
void conv2dBackward(T* dinput,        // (N, Cin, H, W) or null
                    T* dweight,       // (Cout, Cin, kh, kw) or null
                    T* dbias,         // (Cout) or null
                    const T* dout,    // (N, Cout, OH, OW)
                    const T* in,      // (N, Cin, H, W)
                    const T* weight,  // (Cout, Cin, kh, kw)
                    const Conv2dDesc& d);

// ---- ConvTranspose2D (PyTorch semantics) ----------------------------------------------------------
struct ConvTranspose2dDesc {
    int64_t batch = 1, inChannels = 1, inHeight = 1, inWidth = 1;
    int64_t outChannels = 1, kernelHeight = 3, kernelWidth = 3;
    int strideH = 2, strideW = 2;
    int padH = 0, padW = 0;                      // removed from both sides of the full output
    int outputPaddingH = 0, outputPaddingW = 0;  // added after (bottom/right)
    int dilationH = 1, dilationW = 1;
    bool bias = true;

    // (in - 1) * stride - 2 * pad + dilation * (k - 1) + outputPadding + 1
    int64_t outHeight() const;
    int64_t outWidth() const;
    int64_t weightCount() const { return inChannels * outChannels * kernelHeight * kernelWidth; }
    int64_t macs() const {
        return batch * inChannels * inHeight * inWidth * outChannels * kernelHeight * kernelWidth;
    }
    void validate() const;
};

template <class T>
void convTranspose2dForward(T* out,           // (N, Cout, OH, OW)
                            const T* in,      // (N, Cin, H, W)
                            const T* weight,  // (Cin, Cout, kh, kw)
                            const T* bias,    // (Cout) or null
                            const ConvTranspose2dDesc& d);
template <class T>
void convTranspose2dBackward(T* dinput, T* dweight, T* dbias,  // as the forward's in, weight, bias, or null
                             const T* dout,                    // (N, Cout, OH, OW)
                             const T* in, const T* weight, const ConvTranspose2dDesc& d);

// ---- MaxPool2D -------------------------------------------------------------------------------------
struct MaxPool2dDesc {
    int64_t batch = 1, channels = 1, inHeight = 1, inWidth = 1;
    int kernel = 2, stride = 2, padding = 0;  // padded cells never win (-infinity)

    int64_t outHeight() const;  // floor((in + 2 pad - kernel) / stride) + 1
    int64_t outWidth() const;
    void validate() const;
};

// Saves, per output element, the index (h * W + w) of the winning input in its plane. As in PyTorch:
// ties go to the first in row-major window order, and a NaN wins (the last NaN if several).
template <class T>
void maxPool2dForward(T* out,           // (N, C, OH, OW)
                      int32_t* argmax,  // (N, C, OH, OW)
                      const T* in,      // (N, C, H, W)
                      const MaxPool2dDesc& d);
template <class T>
void maxPool2dBackward(T* dinput,      // (N, C, H, W)
                       const T* dout,  // (N, C, OH, OW)
                       const int32_t* argmax, const MaxPool2dDesc& d);

// ---- Element-wise activations over n values ---------------------------------------------------------
enum class Activation { None, ReLU, LeakyReLU, Sigmoid, Clamp };
const char* activationName(Activation activation);
Activation parseActivation(const std::string& name);  // throws dejag::Error

struct ActivationDesc {
    Activation kind = Activation::None;
    float slope = 0.01f;            // LeakyReLU: x < 0 -> slope * x
    float low = 0.0f, high = 1.0f;  // Clamp
};

template <class T>
void activationForward(T* out, const T* in, int64_t n, const ActivationDesc& d);  // out may equal in
// Needs the forward's input `in` (ReLU, LeakyReLU, Clamp) or its output `out` (Sigmoid).
template <class T>
void activationBackward(T* dinput, const T* dout, const T* in, const T* out, int64_t n,
                        const ActivationDesc& d);

// ---- Add (residual) and Concat (channels) -----------------------------------------------------------
template <class T>
void addForward(T* out, const T* a, const T* b, int64_t n);
template <class T>
void addBackward(T* da, T* db, const T* dout, int64_t n);  // da += dout, db += dout (either may be null)

// Concatenates inputs[i] (N, C_i, H, W) along channels into out (N, sum C_i, H, W).
template <class T>
void concatForward(T* out, const std::vector<const T*>& inputs, const std::vector<int64_t>& channels,
                   int64_t batch, int64_t planeSize);
template <class T>
void concatBackward(const std::vector<T*>& dinputs, const T* dout, const std::vector<int64_t>& channels,
                    int64_t batch, int64_t planeSize);

// ---- Resampling -------------------------------------------------------------------------------------
struct ResampleDesc {
    int64_t batch = 1, channels = 1, inHeight = 1, inWidth = 1;
    int factor = 2;
};
// Nearest: out[y, x] = in[y / f, x / f].
template <class T>
void upsampleNearestForward(T* out, const T* in, const ResampleDesc& d);
template <class T>
void upsampleNearestBackward(T* dinput, const T* dout, const ResampleDesc& d);
// Bilinear, PyTorch align_corners=False: source = (dst + 0.5) / f - 0.5, clamped at 0.
template <class T>
void upsampleBilinearForward(T* out, const T* in, const ResampleDesc& d);
template <class T>
void upsampleBilinearBackward(T* dinput, const T* dout, const ResampleDesc& d);
// Pixel shuffle: (N, C f^2, H, W) -> (N, C, H f, W f); `channels` is the input's C f^2.
template <class T>
void pixelShuffleForward(T* out, const T* in, const ResampleDesc& d);
template <class T>
void pixelShuffleBackward(T* dinput, const T* dout, const ResampleDesc& d);

// ---- Kernel filter (the output of a kernel-predicting network) -----------------------------------------
// Each output pixel is a weighted average of its input's k x k neighbourhood (edge pixels repeated past
// the border); the k^2 weights are the softmax of k^2 per-pixel logits, the centre's raised by
// centreBias. The output can only mix colours that are there: it cannot invent a hue, and the identity
// (all weight in the centre) is one logit away.
//   out(n, c, y, x) = sum_j w_j(n, y, x) in(n, c, clamp(y + dy_j), clamp(x + dx_j)),
//   w_j = softmax_j(logits(n, j, y, x) + [j is the centre] centreBias), j = (dy + r) k + (dx + r), r = k / 2.
// With a history (a second image of the same shape, a recurrent network's warped previous output) there
// is one more logit, k^2, whose weight takes the history's own pixel: the softmax then blends the frame's
// neighbourhood and the history, as a TAA blends its history with the current frame.
//   out(n, c, y, x) += w_{k^2}(n, y, x) history(n, c, y, x).
struct KernelFilterDesc {
    int64_t batch = 1, channels = 1, height = 1, width = 1;
    int kernel = 3;  // odd
    float centreBias = 0.0f;
    bool history = false;

    int64_t taps() const { return int64_t(kernel) * kernel; }
    int64_t weights() const { return taps() + (history ? 1 : 0); }  // the logits' channels
    void validate() const;
};

// One pixel's k^2 (+ 1) weights from its logits (contiguous; weights may equal logits).
template <class T>
void kernelFilterWeights(T* weights, const T* logits, const KernelFilterDesc& d);
template <class T>
void kernelFilterForward(T* out,                       // (N, C, H, W)
                         const T* in,                  // (N, C, H, W)
                         const T* logits,              // (N, k^2 (+ 1), H, W)
                         const KernelFilterDesc& d,    //
                         const T* history = nullptr);  // (N, C, H, W) when d.history
template <class T>
void kernelFilterBackward(T* dinput,                    // (N, C, H, W) or null
                          T* dlogits,                   // (N, k^2 (+ 1), H, W) or null
                          const T* dout,                // (N, C, H, W)
                          const T* in,                  // (N, C, H, W)
                          const T* logits,              // (N, k^2 (+ 1), H, W)
                          const KernelFilterDesc& d,    //
                          T* dhistory = nullptr,        // (N, C, H, W) or null, when d.history
                          const T* history = nullptr);  // (N, C, H, W) when d.history

// ---- Accumulate (a TAA's blend with a sample count, the recurrent network's output) ---------------------
// The history holds the running mean of the frames' own samples in linear light (colour) and a confidence
// s = n / (n + 1) of the n samples in it (0: none). Per pixel, k^2 logits weigh the frame's k x k
// neighbourhood (a softmax of the sRGB-encoded colours, as the kernel filter) and one more, the trust,
// keeps rho = min(1, 2 sigmoid(logit)) of the history's samples (all of them from logit 0 up, so that a
// still view keeps every sample without a logit driven to infinity). The frame shown is the mean of the
// kept samples with the filtered neighbourhood; the next history is their mean with the frame's own
// sample, so what is kept is never blurred by the filter; and the means are taken in linear light, as the
// truth's samples are averaged, so a still view converges to the truth of its jittered samples:
//   spatial_c = sum_j softmax_j(logits) image_c(tap j)          n = s / (1 - s), s clamped to [0, N/(N+1)]
//   m = rho n,  a = m / (1 + m)                                  (the history's weight)
//   shown_c = E(D(spatial_c) + a (history_c - D(spatial_c)))     D, E: sRGB decode, encode (clamped to [0,
//   1]) kept_c  = D(image_c) + a (history_c - D(image_c))            (the pixel's own sample) s' = n' / (n' +
//   1),  n' = min(1 + m, N)
// The output has 2 C + 1 channels: shown (sRGB-encoded), kept (linear) and s' (the next frame's history
// is kept and s'). N is `max_count`. docs/nn-kernels.md derives it.
struct AccumulateDesc {
    int64_t batch = 1, channels = 3, height = 1, width = 1;  // channels: the image's (C)
    int kernel = 3;                                          // odd
    float maxCount = 32.0f;                                  // N >= 1
    // Clip: the history's colour is first clamped to the range of the frame's k x k neighbourhood (per
    // channel, the taps' own samples decoded: [D(min), D(max)]), a TAA's neighbourhood clamp; what it
    // removes is a colour the neighbourhood cannot hold. Its gradient goes to the history inside the range
    // and to the bounding tap's sample (the first in tap order) outside.
    bool clip = false;

    int64_t taps() const { return int64_t(kernel) * kernel; }
    void validate() const;
};
template <class T>
void accumulateForward(T* out,            // (N, 2 C + 1, H, W)
                       const T* image,    // (N, C, H, W)
                       const T* logits,   // (N, k^2 + 1, H, W)
                       const T* history,  // (N, C + 1, H, W)
                       const AccumulateDesc& d);
template <class T>
void accumulateBackward(T* dimage,      // (N, C, H, W) or null
                        T* dlogits,     // (N, k^2 + 1, H, W) or null
                        T* dhistory,    // (N, C + 1, H, W) or null
                        const T* dout,  // (N, 2 C + 1, H, W)
                        const T* image, const T* logits, const T* history, const AccumulateDesc& d);
// The sRGB curves (IEC 61966-2-1) on [0, 1] (clamped) and their derivatives (0 outside).
template <class T>
inline T srgbDecode(T v) {
    v = v < T(0) ? T(0) : (v > T(1) ? T(1) : v);
    return v <= T(0.04045) ? v / T(12.92) : std::pow((v + T(0.055)) / T(1.055), T(2.4));
}
template <class T>
inline T srgbDecodeSlope(T v) {
    if (!(v > T(0) && v < T(1))) return T(0);
    return v <= T(0.04045) ? T(1) / T(12.92)
                           : T(2.4) / T(1.055) * std::pow((v + T(0.055)) / T(1.055), T(1.4));
}
template <class T>
inline T srgbEncode(T x) {
    x = x < T(0) ? T(0) : (x > T(1) ? T(1) : x);
    return x <= T(0.0031308) ? x * T(12.92) : T(1.055) * std::pow(x, T(1) / T(2.4)) - T(0.055);
}
template <class T>
inline T srgbEncodeSlope(T x) {
    if (!(x > T(0) && x < T(1))) return T(0);
    return x <= T(0.0031308) ? T(12.92) : T(1.055) / T(2.4) * std::pow(x, T(1) / T(2.4) - T(1));
}
// One pixel's blend: from the spatial filter's colours (summed with the softmax weights of the k^2
// logits), the pixel's own sample, the history's colour and confidence and the trust logit, writes
// shown[0 .. C) and kept[0 .. C) and returns s'. The reference's and the inference plan's.
template <class T>
inline T accumulatePixel(T* shown, T* kept, const T* spatial, const T* sample, const T* history,
                         int64_t channels, T trustLogit, T confidence, T maxCount) {
    const T maxConfidence = maxCount / (maxCount + T(1));
    const T s = confidence < T(0) ? T(0) : (confidence > maxConfidence ? maxConfidence : confidence);
    const T n = s / (T(1) - s), rho = std::min(T(1), T(2) / (T(1) + std::exp(-trustLogit))), m = rho * n;
    const T a = m / (T(1) + m);
    for (int64_t c = 0; c < channels; ++c) {
        const T filtered = srgbDecode(spatial[c]), own = srgbDecode(sample[c]);
        shown[c] = srgbEncode(filtered + a * (history[c] - filtered));
        kept[c] = own + a * (history[c] - own);
    }
    const T next = std::min(T(1) + m, maxCount);
    return next / (next + T(1));
}

// ---- Motion warp (a recurrent network's history read where each pixel was) -------------------------------
// out(n, c, y, x) = image(n, c) read at (x - motion(n, 0, y, x), y - motion(n, 1, y, x)) in pixel indices:
// the motion is what dejag's motion vectors hold (pixels moved since the previous frame, +x right, +y
// down), so the previous frame's pixel p - motion is where p was. Read with a separable filter over the
// taps around that place, each tap's index clamped to the image (edge pixels repeated):
//   bilinear      2 x 2 taps, weights 1 - f, f (PyTorch grid_sample bilinear, border padding);
//   catmull-rom   4 x 4 taps, the cubic convolution kernel with a = -0.5: exact on linear ramps and on
//                 whole-pixel motion, and the least blur of the cubics (what taa-hq reads its history with);
//   bicubic       4 x 4 taps, a = -0.75 (PyTorch's and OpenCV's bicubic: grid_sample bicubic, border).
// Backward: the image's gradient (each tap's weight times the output's), and the motion's (the weights'
// derivative; at a whole pixel of a bilinear read, a kink, the one-sided derivative toward the next tap,
// as PyTorch's; 0 where the read place was clamped).
enum class WarpFilter { Bilinear, CatmullRom, Bicubic };
struct WarpDesc {
    int64_t batch = 1, channels = 1, height = 1, width = 1;
    WarpFilter filter = WarpFilter::Bilinear;
    int taps() const { return filter == WarpFilter::Bilinear ? 2 : 4; }
};
template <class T>
void warpForward(T* out,           // (N, C, H, W)
                 const T* image,   // (N, C, H, W)
                 const T* motion,  // (N, 2, H, W)
                 const WarpDesc& d);
template <class T>
void warpBackward(T* dimage,        // (N, C, H, W) or null
                  T* dmotion,       // (N, 2, H, W) or null
                  const T* dout,    // (N, C, H, W)
                  const T* image,   // (N, C, H, W)
                  const T* motion,  // (N, 2, H, W)
                  const WarpDesc& d);
// The forward warp of one image for inference: up to 4 channels stored interleaved in 4 floats a pixel
// (image[(y W + x) 4 + c]), the motion interleaved in 2 (motion[2 (y W + x) + {0, 1}]), the result as
// planes (out[c][y W + x]). A tap is one 4-float vector, so a pixel costs the taps' loads and not a
// gather per channel. The arithmetic, order of sums included, is warpForward's.
void warpInterleaved(float* const* out, const float* image, const float* motion, int64_t width,
                     int64_t height, int channels, WarpFilter filter);
// The same for one channel stored as a plane (image[y W + x]).
void warpPlane(float* out, const float* image, const float* motion, int64_t width, int64_t height,
               WarpFilter filter);
// "bilinear" | "catmull-rom" | "bicubic"; throws dejag::Error naming the choices.
WarpFilter parseWarpFilter(const std::string& name);
const char* warpFilterName(WarpFilter filter);

}  // namespace dejag::nn
