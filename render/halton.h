// dejag/render: camera jitter. Halton(2,3) with the reverse-radix scrambling of docs/taa.md (base-3
// digits 1 and 2 swapped); the first 16 points are the thesis' table.
#pragma once

#include "render/math.h"

namespace dejag::render {

// Radical inverse of `index` in `base`; with scrambling, base-3 digits 1 <-> 2.
double radicalInverse(unsigned index, unsigned base, bool scrambled);
// Point `index` of the scrambled Halton(2,3) sequence, in [0, 1)^2.
Vec2 haltonPoint(unsigned index);
// The sub-pixel camera offset of a Halton point: spread * (x - 0.5, y - 0.5) pixels, +x right, +y up
// (NDC orientation; docs/taa.md: h = spread * (2x - 1, 2y - 1) / (w, h) in NDC).
Vec2 jitterPixels(unsigned index, double spread);

}  // namespace dejag::render
