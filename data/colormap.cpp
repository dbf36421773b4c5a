#include "data/colormap.h"

#include <algorithm>
#include <cmath>

namespace dejag {

Rgb viridis(float t) {
    static constexpr float kStops[9][3] = {
        {68, 1, 84},    {71, 44, 122}, {59, 81, 139},  {44, 113, 142}, {33, 144, 141},
        {39, 173, 129}, {92, 200, 99}, {170, 220, 50}, {253, 231, 37},
    };
    if (!std::isfinite(t)) t = 0.0f;
    t = std::clamp(t, 0.0f, 1.0f) * 8.0f;
    const int i = std::min(7, int(t));
    const float f = t - float(i);
    Rgb colour;
    colour.r = ((1 - f) * kStops[i][0] + f * kStops[i + 1][0]) / 255.0f;
    colour.g = ((1 - f) * kStops[i][1] + f * kStops[i + 1][1]) / 255.0f;
    colour.b = ((1 - f) * kStops[i][2] + f * kStops[i + 1][2]) / 255.0f;
    return colour;
}

}  // namespace dejag
