#include "render/halton.h"

namespace dejag::render {

double radicalInverse(unsigned index, unsigned base, bool scrambled) {
    double result = 0.0, scale = 1.0 / base;
    while (index > 0) {
        unsigned digit = index % base;
        if (scrambled && base == 3 && digit != 0) digit = 3 - digit;
        result += digit * scale;
        index /= base;
        scale /= base;
    }
    return result;
}

Vec2 haltonPoint(unsigned index) {
    return {radicalInverse(index, 2, true), radicalInverse(index, 3, true)};
}

Vec2 jitterPixels(unsigned index, double spread) {
    const Vec2 p = haltonPoint(index);
    return {spread * (p.x - 0.5), spread * (p.y - 0.5)};
}

}  // namespace dejag::render
