// dejag/data: colour maps for images of a scalar (SSIM maps, error maps).
#pragma once

namespace dejag {

struct Rgb {
    float r, g, b;  // sRGB-encoded, [0, 1]
};

// Matplotlib's viridis (perceptually uniform), sampled at 9 stops and interpolated linearly.
// t is clamped to [0, 1]; NaN maps to 0.
Rgb viridis(float t);

}  // namespace dejag
