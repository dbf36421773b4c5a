// dejag/infer: the ring of padded planar rows the band kernels (TAA, taa-hq) make their inputs into.
//
// A ring keeps the last kRows rows of one kind (each `planes` planes of padded floats), by row index; a
// kernel asks for row y and the ring makes it (clamped to the frame) unless it holds it already. So every
// input row is read from memory once per band and its 3x3 neighbourhoods come from cache.
#pragma once

#include <algorithm>
#include <climits>
#include <cstddef>

namespace dejag::infer {

struct RowRing {
    static constexpr int kRows = 8;  // a power of two
    static constexpr int kPad = 16;  // floats each side of a plane's row

    float* base = nullptr;
    size_t rowFloats = 0;
    int planes = 1;
    int tags[kRows];

    // Takes its rows from `cursor` (advanced past them).
    void carve(float*& cursor, size_t floatsPerRow, int planeCount) {
        base = cursor, rowFloats = floatsPerRow, planes = planeCount;
        cursor += size_t(kRows) * size_t(planes) * rowFloats;
        std::fill(tags, tags + kRows, INT_MIN);
    }
    // Pixel 0 of row y's first plane; plane k is k * rowFloats further.
    float* slot(int y) { return base + size_t(y & (kRows - 1)) * size_t(planes) * rowFloats + kPad; }

    // Row y (clamped to [0, height)) made by fill(y, row) unless held already; the pad pixel left and
    // right of each plane repeats the border pixel (clamp-to-edge for 3x3 reads).
    template <class Fill>
    const float* row(int y, int width, int height, Fill fill) {
        y = std::clamp(y, 0, height - 1);
        float* r = slot(y);
        int& tag = tags[y & (kRows - 1)];
        if (tag != y) {
            fill(y, r);
            for (int k = 0; k < planes; ++k) {
                float* plane = r + size_t(k) * rowFloats;
                plane[-1] = plane[0], plane[width] = plane[width - 1];
            }
            tag = y;
        }
        return r;
    }
};

}  // namespace dejag::infer
