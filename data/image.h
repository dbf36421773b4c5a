// dejag/data: images in memory and on disk.
//
// An Image holds float32 samples interleaved as (H, W, C) with a name per channel, so a lit colour and
// its G-buffers (albedo, depth, motion, IDs) fit in one image and one multi-channel EXR. Samples keep the
// scale of the file they came from: 8- and 16-bit files become [0, 1] (value / 255 or / 65535), half and
// float files keep their raw values. `storage` remembers the file's pixel type so that writing an image
// back keeps 8-bit as 8-bit, 16-bit as 16-bit and float as float.
//
// Colour follows the file: 8- and 16-bit files (PNG, JPEG, integer TIFF) hold sRGB-encoded values, half and
// float files (EXR, float TIFF) linear light. In memory an image keeps the encoding of its `storage`, and
// writeImage() converts the colour channels (R, G, B, Y) when the file it writes holds the other kind.
// Reading never converts.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace dejag {

enum class PixelType { UInt8, UInt16, Half, Float };
const char* pixelTypeName(PixelType type);

struct Image {
    int width = 0;
    int height = 0;
    std::vector<std::string> channelNames;  // e.g. R, G, B, A or albedo.R, depth.Z
    PixelType storage = PixelType::Float;   // pixel type of the file it came from or will go to
    std::vector<float> pixels;              // (H, W, C)

    Image() = default;
    Image(int width, int height, std::vector<std::string> channelNames, PixelType storage = PixelType::Float);
    // Channel names Y / YA / RGB / RGBA for 1-4 channels, C0.. beyond.
    static std::vector<std::string> defaultChannelNames(int channels);

    int channels() const { return int(channelNames.size()); }
    size_t pixelCount() const { return size_t(width) * size_t(height); }
    size_t sampleCount() const { return pixelCount() * size_t(channels()); }
    float* row(int y) { return pixels.data() + size_t(y) * size_t(width) * size_t(channels()); }
    const float* row(int y) const { return pixels.data() + size_t(y) * size_t(width) * size_t(channels()); }
    float& at(int x, int y, int c) { return row(y)[size_t(x) * channels() + c]; }
    float at(int x, int y, int c) const { return row(y)[size_t(x) * channels() + c]; }
    int findChannel(std::string_view name) const;  // -1 if absent
    // "R,G,B"
    std::string channelList() const;
    // "800x600, 3 channels (R,G,B), uint8"
    std::string describe() const;
};

// The named channels of an image, in the order given: e.g. R, G, B of a dataset input that also holds
// albedo, depth, motion and id. Throws dejag::Error naming the first channel the image lacks.
Image selectChannels(const Image& image, const std::vector<std::string>& names);

// The most samples (width x height x channels) readImage() accepts: 2^28, e.g. 8192 x 8192 RGBA, 1 GiB
// of floats. A larger header is refused before any pixel is read.
inline constexpr int64_t kMaxImageSamples = int64_t(1) << 28;

// Reads the first subimage of a PNG, JPEG, TIFF or EXR (anything OpenImageIO reads) with all its
// channels. Throws dejag::Error naming the file if it is missing, unreadable, truncated or implausible,
// or holds more than maxSamples samples.
Image readImage(const std::string& path, int64_t maxSamples = kMaxImageSamples);

struct WriteOptions {
    std::optional<PixelType> storage;  // default: image.storage, or the nearest type the format holds
    int jpegQuality = 95;
};

// Writes atomically and durably (base/files.h: encoded in memory, then a temporary file, fsync, rename). The
// format follows the extension; colour channels are encoded or decoded when the file's kind (sRGB or
// linear) differs from the image's. Throws dejag::Error if the format cannot hold the image (e.g. 5
// channels in a PNG) or the file cannot be written, naming the file and the reason; an earlier file of
// that name is then intact.
void writeImage(const std::string& path, const Image& image, const WriteOptions& options = {});

// The value scale of a pixel type: 255 for 8-bit, 65535 for 16-bit, 1 for half and float. Multiplying an
// in-memory sample by it gives the value on the file's own scale (the 0-255 scale of 8-bit metrics).
double valueScale(PixelType type);

// True for half and float storage (linear light), false for 8- and 16-bit (sRGB-encoded).
bool holdsLinearLight(PixelType type);

// sRGB transfer function, IEC 61966-2-1 (piecewise: linear below 0.04045 / 0.0031308). The encoding is
// base/srgb.h's curve (within 2e-7 of the formula), which the SIMD kernels and the GLSL passes repeat bit
// for bit.
float srgbToLinear(float encoded);
float linearToSrgb(float linear);
// Apply to colour channels only (R, G, B, Y, with or without a layer prefix); alpha and buffers untouched.
void convertSrgbToLinear(Image& image);
void convertLinearToSrgb(Image& image);

// First non-finite sample, if any: {x, y, channel}.
struct SamplePosition {
    int x, y, channel;
};
std::optional<SamplePosition> findNonFinite(const Image& image);

}  // namespace dejag
