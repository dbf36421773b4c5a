#include "base/fft.h"

#include <numbers>
#include <string>

#include "base/error.h"
#include "base/thread_pool.h"

namespace dejag {

using Complex = std::complex<double>;

void fft(Complex* v, int n) {
    if (n < 1 || (n & (n - 1)) != 0)
        throw Error("fft: the length " + std::to_string(n) + " is no power of two");
    for (int i = 1, j = 0; i < n; ++i) {  // bit-reversed order
        int bit = n >> 1;
        for (; j & bit; bit >>= 1) j ^= bit;
        j ^= bit;
        if (i < j) std::swap(v[i], v[j]);
    }
    for (int length = 2; length <= n; length *= 2) {
        const double angle = -2 * std::numbers::pi / length;
        const Complex step(std::cos(angle), std::sin(angle));
        for (int start = 0; start < n; start += length) {
            Complex w(1, 0);
            for (int k = 0; k < length / 2; ++k) {
                const Complex a = v[start + k], b = v[start + k + length / 2] * w;
                v[start + k] = a + b, v[start + k + length / 2] = a - b;
                w *= step;
            }
        }
    }
}

void fft2d(std::vector<Complex>& values, int h, int w) {
    if (size_t(h) * size_t(w) != values.size()) throw Error("fft2d: the array is not h x w");
    parallelFor(0, h, 8, [&](int64_t first, int64_t last) {
        for (int64_t y = first; y < last; ++y) fft(values.data() + y * w, w);
    });
    parallelFor(0, w, 8, [&](int64_t first, int64_t last) {
        std::vector<Complex> column(static_cast<size_t>(h));
        for (int64_t x = first; x < last; ++x) {
            for (int y = 0; y < h; ++y) column[size_t(y)] = values[size_t(y) * size_t(w) + size_t(x)];
            fft(column.data(), h);
            for (int y = 0; y < h; ++y) values[size_t(y) * size_t(w) + size_t(x)] = column[size_t(y)];
        }
    });
}

void inverseFft2d(std::vector<Complex>& values, int h, int w) {
    for (Complex& v : values) v = std::conj(v);
    fft2d(values, h, w);
    const double scale = 1.0 / (double(h) * double(w));
    for (Complex& v : values) v = std::conj(v) * scale;
}

}  // namespace dejag
