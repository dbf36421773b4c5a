// dejag/infer: SMAA 1x (Jimenez et al., Eurographics 2012) on the CPU, in its three passes (docs/smaa.md):
//   1. edges: a pixel's left and top boundaries are edges where the luma (or colour) step across them
//      reaches the threshold and is not much smaller than the other steps around (local contrast
//      adaptation); with predication, a depth step lowers the threshold;
//   2. blending weights: for each edge, the run it belongs to is searched along both ways (and, with
//      diagonal steps, along the diagonals first), the crossing edges at its ends give its pattern, and
//      the pattern's area (infer/smaa_area.h) over the pixel is how much it takes from across the edge;
//      sharp corners keep part of their shape (corner rounding);
//   3. blending: each pixel mixes with its neighbours by those weights, in linear light.
// The frame is display-referred (sRGB-encoded), as SMAA expects of its edge detection.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "infer/filter.h"

namespace dejag::infer {

enum class SmaaEdges { Luma, Colour };

struct SmaaOptions {
    float threshold = 0.05f;  // edge detection threshold, (0, 0.5]
    int searchSteps = 32;     // orthogonal search: runs of up to 2 x steps pixels each way, [1, 112]
    int diagonalSteps = 16;   // diagonal search steps, [0, 20] (0: no diagonal patterns)
    int cornerRounding = 25;  // percent of a sharp corner rounded, [0, 100] (100: no corner detection)
    SmaaEdges edges = SmaaEdges::Luma;
    bool predication = false;  // lower the threshold where the depth also steps (needs depth)
    float predicationThreshold = 0.01f, predicationScale = 2.0f, predicationStrength = 0.4f;
    bool linearBlending = true;  // mix in linear light (an sRGB texture read), else on encoded values
};

// The published presets: "low", "medium", "high", "ultra" (threshold, search and diagonal steps, corner
// rounding). Throws dejag::Error naming the presets for any other name.
SmaaOptions smaaPreset(const std::string& name);

class Smaa {
  public:
    // Throws dejag::Error for settings out of range.
    explicit Smaa(const SmaaOptions& options = {});

    // in, out: (height, width, channels) interleaved, channels >= 3, R G B sRGB-encoded in [0, 1]; further
    // channels are copied. depth: (height, width) or null (needed with predication). in may equal out.
    // Threaded by rows; the result does not depend on the thread count. Allocates only when the frame grows.
    void apply(const float* in, float* out, int width, int height, int channels,
               const float* depth = nullptr);

    const SmaaOptions& options() const { return options_; }
    // Share of the pixels of the last apply() with an edge (pass 2's work).
    double edgeFraction() const { return edgeFraction_; }
    // The last apply()'s edges: bit 0 the pixel's left boundary, bit 1 its top; and its weights (near and
    // far of the top edge, near and far of the left edge; zero where a pixel has no edge). For tests.
    uint8_t edgeAt(int x, int y) const { return edges_[size_t(y + pad_) * edgeStride_ + size_t(x + pad_)]; }
    const float* weightsAt(int x, int y) const;
    // The length in pixels of the longest run (of top edges along the row, of left edges along the column)
    // through (x, y) of the last apply(), as the searches find it (up to 4 x search steps); 0 without edge.
    int runLength(int x, int y) const;

  private:
    SmaaOptions options_;
    int width_ = 0, height_ = 0, pad_ = 0;
    size_t edgeStride_ = 0, lumaStride_ = 0;
    std::vector<uint8_t> edges_;  // zero-padded by pad_ on every side
    std::vector<float> luma_;     // rows with 2 pixels of clamp-to-edge padding left and right
    std::vector<float> weights_;  // 4 per pixel, written only where the pixel has an edge
    std::vector<float> copy_;     // the input, when in == out
    std::vector<int64_t> edgeCounts_;
    double edgeFraction_ = 0;
};

// The run of top edges through pixel (x, y) of an edge plane laid out as Smaa's (bit 1: top edge, bit 0:
// left; `pad` zero pixels around): its first and last pixel. Leftwards it goes on while the next pixel has
// a top edge and no crossing (left) edge in the run's two rows lies between them, for at most
// 2 steps - 1 pixels; rightwards for at most 2 steps. These are the ends SMAA's bilinear search with its
// search texture finds (tested against it).
void smaaHorizontalRun(const uint8_t* edges, size_t stride, int pad, int x, int y, int steps, int& first,
                       int& last);
// The same along the column of left edges through (x, y) (the transposed search): its first and last row.
void smaaVerticalRun(const uint8_t* edges, size_t stride, int pad, int x, int y, int steps, int& first,
                     int& last);

// The method "smaa" of infer/filter.h: parameters preset, threshold, search-steps, diagonal-steps,
// corner-rounding, edges, predication, linear; uses depth when predication is on.
MethodSpec smaaMethod();
// The options the method's parameters give (shared with its GPU form, infer/glsl_filter.h).
SmaaOptions smaaOptions(const MethodParameters& parameters);

}  // namespace dejag::infer
