// dejag/data: aliasing measured in the frequency domain (docs/metrics.md, "Aliasing"): how much of an
// image's spectrum no smooth filtering of its truth explains, beside how much of the truth's detail it
// keeps. Blur, sharpening and a texture's MIP-map prefilter are smooth filters of the truth, so they cost
// detail and not aliasing; frequencies folded back from beyond the Nyquist limit, moiré and crawling
// patterns are not, so they are aliasing.
#pragma once

#include <vector>

#include "base/fft.h"
#include "data/image.h"

namespace dejag {

struct AliasingScore {
    double aliasing = 0;    // the residual's energy over the truth's (0: none; 1: as much as the truth)
    double detailKept = 0;  // the truth's energy the image holds, as a fraction (1: all of it)
    int rings = 0, sectors = 0;
    // 10 log10(aliasing): -inf for none.
    double aliasingDb() const;
};

// The measure on the luma of the colour channels (base/luma.h; the values as stored) of `test` against
// `truth`, both of one size: each minus its mean, under a Hann window, zero-padded to powers of two and
// transformed; the frequency plane cut into `rings` rings (by |f|, up to the corner's sqrt(2)/2 cycles a
// pixel) and `sectors` orientations over [0, pi); in each band b the truth's part of the image is its
// least-squares real gain g_b = sum Re(X T*) / sum |T|^2 (a zero-phase filter constant over the band),
// clamped to [0, (pi/2)^2] (no filter amplifies more than undoing the pixel's box filter at the Nyquist
// corner does), and the residual X - g_b T is the aliasing:
//   aliasing = sum |X - g_b T|^2 / sum |T|^2,   detail kept = sum min(|X|^2, |T|^2) / sum |T|^2.
// Throws dejag::Error for different sizes, no colour channel, or a truth with no detail (a constant).
AliasingScore aliasingScore(const Image& test, const Image& truth, int rings = 32, int sectors = 8);

}  // namespace dejag
