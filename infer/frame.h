// dejag/infer: a frame as the anti-aliasing methods see it — colour plus the optional named buffers a
// renderer can give (albedo, depth, motion, object ids, the previous frame's depth, the camera jitter) —
// and how a frame is taken from an image file whose channels may be named any way (ChannelMap).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "data/image.h"

namespace dejag::infer {

// The optional buffers of a frame, as bits of a BufferSet.
enum class Buffer : unsigned {
    Albedo = 1u << 0,         // 3 channels, sRGB-encoded like the colour
    Depth = 1u << 1,          // 1 channel, linear depth divided by the far plane ([0, 1])
    Motion = 1u << 2,         // 2 channels, pixels moved since the previous frame, +x right, +y down
    Ids = 1u << 3,            // 1 channel, object ids
    PreviousDepth = 1u << 4,  // 1 channel, the previous frame's depth at this pixel / far
    Jitter = 1u << 5,         // the frame's camera jitter in pixels (x right, y down)
};
using BufferSet = unsigned;
inline constexpr BufferSet operator|(Buffer a, Buffer b) {
    return unsigned(a) | unsigned(b);
}
inline constexpr BufferSet operator|(BufferSet a, Buffer b) {
    return a | unsigned(b);
}
inline constexpr bool contains(BufferSet set, Buffer b) {
    return (set & unsigned(b)) != 0;
}
// In the order frames are checked for them (depth and motion first: every temporal method needs them).
inline constexpr Buffer kBuffers[] = {Buffer::Depth, Buffer::Motion,        Buffer::Albedo,
                                      Buffer::Ids,   Buffer::PreviousDepth, Buffer::Jitter};
// "albedo", "depth", "motion", "id", "prevdepth", "jitter" (dejag render --buffers' words).
const char* bufferName(Buffer buffer);
// "depth, motion" (empty: "none").
std::string bufferList(BufferSet set);

// "a,,b" -> {a, "", b}: the comma-separated fields of a list, empty ones kept (for the errors).
std::vector<std::string> splitFields(const std::string& text);

// One frame: all planes (height, width, k) interleaved floats; a buffer the frame lacks is null.
struct Frame {
    int width = 0, height = 0;
    int channels = 3;               // of colour: R G B first, further channels (alpha) pass through
    const float* colour = nullptr;  // sRGB-encoded, [0, 1]
    const float* albedo = nullptr;
    const float* depth = nullptr;
    const float* motion = nullptr;
    const float* ids = nullptr;
    const float* previousDepth = nullptr;
    bool hasJitter = false;
    float jitter[2] = {0, 0};
    bool has(Buffer buffer) const;
};

// For a method that works on R G B alone: a frame's R G B when its colour has more channels (alpha, other
// layers), and the method's result written back with those channels passed through. For a 3-channel frame
// it hands out the frame's own colour and the caller's output, and copies nothing. Allocates only when the
// frame grows.
class RgbScratch {
  public:
    const float* rgb(const Frame& frame);           // the frame's R G B, interleaved
    float* result(const Frame& frame, float* out);  // where the method writes its R G B
    void finish(const Frame& frame, float* out);    // out: the result's R G B, the frame's other channels

  private:
    std::vector<float> rgb_, result_;
};

// Which channels of a file hold colour and each buffer. The defaults are dejag render's names; the
// "blender" preset names the passes of a Blender multilayer EXR of view layer "ViewLayer". A name
// prefixed with '-' is read negated (a motion convention with y up, or pointing the other way).
struct ChannelMap {
    std::vector<std::string> colour = {"R", "G", "B"};
    std::array<std::vector<std::string>, 5> buffers;  // Albedo .. PreviousDepth (not Jitter)
    ChannelMap();                                     // dejag's names
    // "dejag" or "blender"; throws dejag::Error otherwise.
    static ChannelMap preset(const std::string& name);
    // "depth=Z", "motion=-Vector.X,Vector.Y", "color=Combined.R,Combined.G,Combined.B"; throws
    // dejag::Error naming a buffer it does not know or the wrong number of channels.
    void assign(const std::string& assignment);
    const std::vector<std::string>& namesOf(Buffer buffer) const;
};

// A frame read from an image, owning its planes; frame() views them.
struct FrameData {
    int width = 0, height = 0;
    std::vector<std::string> colourNames;  // the file's names of the colour channels kept
    std::vector<float> colour, albedo, depth, motion, ids, previousDepth;
    bool hasJitter = false;
    float jitter[2] = {0, 0};
    Frame frame() const;
};

struct FrameOptions {
    ChannelMap channels;
    BufferSet wanted = 0;    // read these buffers when the file has them
    BufferSet required = 0;  // ... and refuse a file that lacks one of these
    double depthFar = 1;     // depth and previous depth are divided by it
    // Keep every channel of the file after R G B in the colour (alpha and other layers pass through
    // the filters), as long as the colour is the file's first three channels; else only R G B (and A).
    bool keepExtraChannels = true;
};

// Takes a frame out of an image: colour encoded to sRGB when the file holds linear light. Throws
// dejag::Error naming the file, the channel it looked for and the buffer (and how to name another
// channel) if a required buffer is missing.
FrameData frameFromImage(const Image& image, const FrameOptions& options, const std::string& path);

// The largest finite depth below 1e9 in the image's depth channel (the far plane of a sequence whose
// background depth is "infinite"), or 0 if it has none.
double largestFiniteDepth(const Image& image, const ChannelMap& channels);

}  // namespace dejag::infer
