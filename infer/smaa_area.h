// dejag/infer: SMAA's pattern areas (docs/smaa.md). An edge found by SMAA is a run of pixel boundaries
// with a crossing edge (or none) at each end; the run's shape says where the true edge line lies, and the
// area between that line and the boundary over one pixel is how much of the neighbour's colour the pixel
// takes. These functions compute those areas from the pattern definitions — the orthogonal ones exactly,
// the diagonal ones by counting 30 x 30 point samples per pixel, as the published area texture does — and
// lay them out as SMAA's published area and search textures (RG8 160 x 560, R8 64 x 16) for GPU ports.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace dejag::infer {

// A crossing edge at one end of an orthogonal run, by side: "near" crosses the run on the side of the
// pixel being filtered (below a horizontal run, right of a vertical one), "far" on the other side.
// The pattern of a run: near-left 1, near-right 2, far-left 4, far-right 8 (the published numbering).
inline int smaaOrthogonalPattern(bool nearLeft, bool nearRight, bool farLeft, bool farRight) {
    return int(nearLeft) | int(nearRight) << 1 | int(farLeft) << 2 | int(farRight) << 3;
}

// The two areas of orthogonal pattern `pattern` (0..15) for the pixel `left` pixels from the run's left
// end and `right` from its right end: {near, far}: the share of the pixel on the near side to be taken
// from across the run, and the share of the far pixel to be taken from the near side. `offset` shifts
// the revectorised line across the run (0 for SMAA 1x; the published texture holds 7 offsets).
std::array<float, 2> smaaOrthogonalArea(int pattern, int left, int right, float offset = 0.0f);

// The diagonal pattern of crossing codes c1, c2 in 0..3 at the run's two ends (bit 0: a vertical crossing
// edge there, bit 1: a horizontal one, as SMAA's diagonal search reports them).
int smaaDiagonalPattern(int c1, int c2);
// The two areas of diagonal pattern `pattern` for the pixel `left` steps from one end and `right` from
// the other, by sampling; offsets (dx, dy) as the published texture's 5 diagonal subtextures.
std::array<float, 2> smaaDiagonalArea(int pattern, int left, int right, float offsetX = 0.0f,
                                      float offsetY = 0.0f);

// The diagonal areas of offset 0 for distances 0..kSmaaDiagonalMax-1, computed once (thread-safe) and
// shared: [pattern][left][right][2].
inline constexpr int kSmaaDiagonalMax = 20;
const float* smaaDiagonalAreaTable();
inline const float* smaaDiagonalAreas(const float* table, int pattern, int left, int right) {
    return table +
           ((size_t(pattern) * kSmaaDiagonalMax + size_t(left)) * kSmaaDiagonalMax + size_t(right)) * 2;
}

// SMAA's published area texture: 160 x 560 texels of 2 bytes (R, G), rows top first. Left half: the 16
// orthogonal patterns in a 5 x 5 grid of 16 x 16 blocks indexed by the square roots of the distances;
// right half: the 16 diagonal patterns in a 4 x 4 grid of 20 x 20 blocks; 7 orthogonal and 5 diagonal
// subpixel offsets stacked vertically. Values are area * 255, truncated.
inline constexpr int kSmaaAreaTextureWidth = 160, kSmaaAreaTextureHeight = 560;
std::vector<uint8_t> smaaAreaTexture();
// SMAA's published search texture: 64 x 16 texels of 1 byte: for the bilinear fetch of four edges that
// ended a search (r along x, g along y), how many pixels of the last step (0, 1 or 2) the run still
// covers, times 127; left searches in the left 33 columns, right searches from column 33.
inline constexpr int kSmaaSearchTextureWidth = 64, kSmaaSearchTextureHeight = 16;
std::vector<uint8_t> smaaSearchTexture();

}  // namespace dejag::infer
