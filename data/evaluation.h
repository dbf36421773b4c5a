// dejag/data: whole-image evaluation of an anti-aliasing method on one split of a dataset.
//
// Every method (no AA, FXAA, a network) is scored the same way: on the sRGB-encoded image in [0, 1]
// against the truth, over three regions (docs/seed-cnn.md asks for the last two):
//   whole    every pixel;
//   edge     pixels within 1 px of a geometric edge (an object-ID change, or a depth jump between
//            4-neighbours: inverse depth extrapolated from either side misses the other by > 5 %, which
//            keeps planes at grazing angles out): where geometric aliasing lives;
//   texture  pixels at least 3 px from every geometric edge whose truth has detail (3x3 luma range
//            above 0.04): surface texture a filter must keep sharp, not blur.
// PSNR and SSIM as data/metrics.h computes them (data range 1); averages are means over images of the
// per-image figures, as the published tables report them.
#pragma once

#include <string>
#include <vector>

#include "data/dataset.h"
#include "data/image.h"

namespace dejag::data {

enum class Region { Whole, Edge, Texture, Count };
const char* regionName(Region region);

struct EvaluationItem {
    int index = 0;
    std::string id, family;
    Image input, truth;                    // R G B, sRGB-encoded, clamped to [0, 1]
    Image masks[int(Region::Count)];       // one channel each: 1 inside the region, 0 outside
    bool hasRegion[int(Region::Count)]{};  // the region holds enough pixels to score (>= 64)
};

// Items of `split` (all, or `limit` of them spread evenly over the split's manifest order), of the given
// families only if any. Throws dejag::Error if none is left or an item cannot be read.
std::vector<EvaluationItem> loadEvaluationItems(const std::string& folder, Split split, int limit = 0,
                                                const std::vector<std::string>& families = {});

// Region masks of an item from its rendered buffers (id.ID, depth.Z) and its truth (sRGB RGB).
void computeRegionMasks(EvaluationItem& item, const Image& buffers);
// The masks of a rendered frame outside any dataset: `truth` is its sRGB RGB truth (width x height x 3),
// `buffers` its id.ID and depth.Z. Returns the item with truth and masks set (`name` as its id).
EvaluationItem regionsOfFrame(const std::string& name, const std::vector<float>& truth, int width, int height,
                              const Image& buffers);

// Luma 0.21 R + 0.72 G + 0.07 B of an RGB image (the seed network's grey input), one channel "Y".
Image lumaImage(const Image& rgb);

struct RegionScore {
    double psnr = 0, ssim = 0;
    bool scored = false;
};
struct ImageScore {
    RegionScore region[int(Region::Count)];
    bool nonFinite = false;  // the output held a NaN or an infinity: scored kWorstPsnr and SSIM -1
};
inline constexpr double kWorstPsnr = 0.0;
// Scores `output` (same size as the item; 3 channels, or 1 channel compared with the truth's luma).
ImageScore scoreImage(const EvaluationItem& item, const Image& output);

// Means over images of each region's PSNR and SSIM (images whose region is empty are left out).
struct ScoreSummary {
    double psnr[int(Region::Count)]{}, ssim[int(Region::Count)]{};
    int images[int(Region::Count)]{};
    int nonFiniteImages = 0;  // images whose output was not finite (each scored as the worst)
    void add(const ImageScore& score);
    void finish();  // turns the sums into means (NaN for a region no image has)
};

}  // namespace dejag::data
