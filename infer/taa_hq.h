// dejag/infer: taa-hq, a temporal anti-aliasing that converges (docs/taa-hq.md).
//
// What it keeps per pixel: the history colour in linear light and the number of samples it holds (its
// accumulated weight). Each frame:
//   1. the current sample that lies inside the pixel is taken at its true position: every sample of a
//      frame is shifted by the same jitter, so for pixel p it is the sample of pixel p - round(offset),
//      where offset (the sample's position from p's centre) is minus the frame's jitter (a box
//      reconstruction kernel: the truth's pixel filter);
//   2. the history is fetched where the pixel was (p - motion, the motion of the nearest surface in the
//      3x3 neighbourhood when there is depth), resampled with a 4x4 Catmull-Rom and deringed to its 2x2
//      bilinear footprint — a static view reads it exactly;
//   3. it is rejected (its weight set to 0) off screen, and where the previous frame's depth at that
//      place differs from the current depth by more than a tolerance (a disocclusion);
//   4. it is clipped in YCoCg to the current 3x3 neighbourhood's mean ± gamma sigma intersected with its
//      min/max box (and widened to hold the current sample), toward the box's centre; a history that had
//      to be clipped keeps at most `clippedSamples` of its weight. Where nothing moved in the 3x3, now
//      and in the previous frame where the history comes from (the static lock), it is not clipped:
//      its mean holds samples the current 3x3 need not show (a surface thinner than a pixel);
//   5. the weight grows by one sample up to maxSamples (movingSamples where something moved in the 3x3)
//      and the history moves toward the current sample by 1 / weight: a static view averages its
//      jittered frames (the supersampled mean), a fresh or disoccluded pixel takes the current sample at
//      once;
//   6. the output is the history encoded to sRGB, sharpened (when asked) on the output only.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "infer/filter.h"

namespace dejag::infer {

struct TaaHqOptions {
    float clipGamma = 1.25f;       // variance clipping: mean +- gamma sigma (YCoCg), within min/max
    int maxSamples = 32;           // the accumulated weight's cap: the current share never falls below 1/32
    int movingSamples = 6;         // the cap where something moved in the pixel's 3x3 (at most maxSamples)
    float clippedSamples = 4.0f;   // the weight a clipped history keeps at most
    float depthTolerance = 0.05f;  // relative depth change beyond which the history is disoccluded
    float sharpen = 0.0f;          // output-only sharpen, 0 (off) to 1
    bool catmullRom = true;        // history resampling: Catmull-Rom (deringed), else bilinear
    bool staticLock = true;        // no clipping where nothing moved in the 3x3 neighbourhood
    // The jitter of frame k since the last reset: empty means each frame's own (Frame::jitter, zero if
    // it has none); else this list, cycled (image shift in pixels, +x right, +y down).
    std::vector<std::pair<float, float>> jitterList;
};

// "x,y x,y ..." -> the list; throws dejag::Error naming the bad entry.
std::vector<std::pair<float, float>> parseJitterList(const std::string& text);

class TaaHq {
  public:
    explicit TaaHq(const TaaHqOptions& options = {});
    // colour: sRGB-encoded RGB (width x height x 3, interleaved); motion: 2 channels (pixels moved since
    // the previous frame, +y down); depth and previousDepth: 1 channel each, optional (both or neither
    // used); jitter: the frame's image shift (pixels, +y down). out: sRGB RGB. Allocates only when the
    // size changes.
    void apply(int width, int height, const float* colour, const float* motion, const float* depth,
               const float* previousDepth, float jitterX, float jitterY, float* out);
    void reset() { width_ = height_ = 0, frame_ = 0; }
    int framesSinceReset() const { return frame_; }
    const TaaHqOptions& options() const { return options_; }

  private:
    TaaHqOptions options_;
    int width_ = 0, height_ = 0, frame_ = 0;
    size_t stride_ = 0;  // floats per history row
    int bands_ = 0;
    // R, G, B (linear) and the signed weight (negative: something moved in the 3x3) as planes.
    std::vector<float> history_, nextHistory_;
    std::vector<float> scratch_;  // the band kernels' rows (infer/taa_hq_kernels.h)
};

// The method "taa-hq" of infer/filter.h.
MethodSpec taaHqMethod();
// The options the method's parameters give (shared with its GPU form, infer/glsl_filter.h).
TaaHqOptions taaHqOptions(const MethodParameters& parameters);

}  // namespace dejag::infer
