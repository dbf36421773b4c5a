// dejag/base: the discrete Fourier transform of power-of-two sizes (radix 2), in one dimension and in two
// on the thread pool. Used by the aliasing measure (data/spectrum.h) and the Fourier texture sampler's
// precomputation (render/fourier_texture.h).
#pragma once

#include <complex>
#include <vector>

namespace dejag {

// The in-place discrete Fourier transform of n = 2^k values (forward: e^{-2 pi i k n / N}, unscaled).
// Throws dejag::Error for another length.
void fft(std::complex<double>* values, int n);
// Of an h x w array (row-major), both sides powers of two: rows, then columns, on the thread pool.
void fft2d(std::vector<std::complex<double>>& values, int h, int w);
// The inverse of fft2d, scaled by 1 / (h w): fft2d then inverseFft2d gives the values back.
void inverseFft2d(std::vector<std::complex<double>>& values, int h, int w);

}  // namespace dejag
