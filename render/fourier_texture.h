// dejag/render: Fourier texture filtering (docs/texture-aa.md). A texture's MIP levels are band-limited
// hard (level m keeps only the frequencies below `cutoff` times its Nyquist limit, so bilinear reads of it
// cannot alias), and the frequencies they drop come back per pixel as sinusoids, each attenuated by the
// response of a Gaussian pixel filter mapped through the pixel's footprint: a sinusoid the footprint
// resolves keeps its amplitude, one it does not fades instead of folding back as aliasing.
//
// The removed frequencies are kept in sets by (level m, sub-level s, orientation a): the pixel's footprint
// ellipse in texels has its major axis 2^(m + f) (m = floor, f the fraction: the blend of levels m and
// m + 1), its minor axis 2^(s + ...), and its major axis' angle in one of four 45-degree bins around 0,
// 45, 90 and 135 degrees. With `probes` P > 1 an anisotropic footprint reads the bands at 2^p points
// along its major axis, p = min(m - s, log2 P), each at level m - p (its share of the axis), and the
// set of (m, s, a) holds the frequencies that finer band lacks. A set holds the `frequencies` sinusoids above
// level m + 1's cut-off with the largest amplitude times the attenuation a footprint of the set's smallest
// size and its orientation gives them: those that can matter for the pixels that read it.
//
// FourierTexture::sample is the shader's arithmetic in double (render/renderer.cpp's fourierSample), the
// reference the renderer is tested against.
#pragma once

#include <array>
#include <vector>

#include "render/math.h"
#include "render/scene.h"

namespace dejag::render {

class FourierTexture {
  public:
    static constexpr int kOrientations = 4;

    // Square power-of-two textures from 2 x 2 up; the colour is decoded from sRGB, alpha kept linear.
    // Throws dejag::Error for another size or options out of range.
    FourierTexture(const TextureImage& image, const FourierOptions& options);

    int size() const { return size_; }
    int levels() const { return levels_; }  // log2(size) + 1; the last is 1 x 1
    int frequencies() const { return options_.frequencies; }
    const FourierOptions& options() const { return options_; }
    // Sets for the level pairs (m, m + 1), m in [0, levels - 2], sub-levels s in [0, m], 4 orientations.
    int setCount() const;
    int setIndex(int level, int subLevel, int orientation) const;
    // Level m: levelSize(m)^2 RGBA floats in linear light, row 0 first. Level 0 is the texture itself;
    // level m >= 1 is stored at twice its MIP size, size >> (m - 1), so that a bilinear read of its band
    // stays within 1/255 of the band itself (docs/texture-aa.md).
    const std::vector<float>& level(int m) const { return bands_[size_t(m)]; }
    int levelSize(int m) const { return m == 0 ? size_ : size_ >> (m - 1); }
    // setCount() rows of frequencies() entries of 8 floats: kx, ky (cycles over the texture, signed),
    // then the complex amplitude of R, G and B (Re, Im) of the sinusoid Re(c e^{2 pi i k.(uv - 1/2N)}).
    // Unused entries are zero.
    const std::vector<float>& detail() const { return detail_; }
    // Per set: the share of the attenuated energy above its cut-off that its sinusoids hold (1: all, or
    // what they miss is below half an 8-bit step of RMS amplitude).
    double captured(int set) const { return captured_[size_t(set)]; }
    // The highest frequency (max(|kx|, |ky|), cycles over the texture) level m holds, exclusive; level 0
    // holds all of them (infinity).
    double cutoffOf(int m) const;

    // The filtered colour (linear RGBA) at `uv` (the texture repeating) for a pixel whose uv changes by
    // `dUvdx` and `dUvdy` a pixel.
    std::array<double, 4> sample(Vec2 uv, Vec2 dUvdx, Vec2 dUvdy) const;
    // Whether this footprint's set captured less than options().minCaptured: sample() then reads the box
    // MIP chain instead (trilinear at each probe), as the sum would ring.
    bool fallsBack(Vec2 dUvdx, Vec2 dUvdy) const;
    // The box MIP chain of the linear texture: level j is size >> j texels across, RGBA; level 0 is
    // level(0).
    const std::vector<float>& mipmap(int j) const { return j == 0 ? bands_[0] : mipmaps_[size_t(j)]; }
    // The detail texture the shader reads: a row per set, 2 texels (RGBA) per sinusoid as in detail(),
    // then one texel holding captured(set).
    std::vector<float> detailTexels() const;

  private:
    // Where a footprint (in texels) reads: its set (level, sub-level s, orientation), the band level m
    // read and its blend f toward m + 1, and the probes along the major axis (`step` apart in uv,
    // centred on the pixel).
    struct Reading {
        int level = 0, s = 0, orientation = 0, m = 0, probes = 1;
        double f = 0;
        Vec2 step{0, 0};
    };
    Reading readingOf(Vec2 a, Vec2 b) const;
    // The band level the sets of (level, subLevel) are read with: level - min(level - subLevel,
    // log2(probes)), the level itself with one probe.
    int bandLevel(int level, int subLevel) const;
    std::array<double, 4> bilinear(int m, Vec2 uv) const;
    static std::array<double, 4> bilinearOf(const std::vector<float>& texels, int size, Vec2 uv);
    std::array<double, 4> mipmapped(const Reading& r, Vec2 uv) const;

    int size_ = 0, levels_ = 0;
    FourierOptions options_;
    std::vector<std::vector<float>> bands_, mipmaps_;  // mipmaps_[0] unused (bands_[0])
    std::vector<float> detail_;
    std::vector<double> captured_;
};

// The footprint of a pixel in texels: its ellipse's axes (log2 of their lengths) and the angle of its
// major axis in [0, pi). Shared by FourierTexture::sample and the tests.
struct Footprint {
    double majorLod = 0, minorLod = 0, angle = 0;
};
Footprint footprintOf(Vec2 dTexelDx, Vec2 dTexelDy);

}  // namespace dejag::render
