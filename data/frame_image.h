// dejag/data: a rendered frame (render::Frame) as an Image (float storage, its pixels moved), or some of
// its channels as a buffer of their own.
#pragma once

#include <algorithm>
#include <utility>
#include <vector>

#include "data/image.h"
#include "render/renderer.h"

namespace dejag {

inline Image imageFromFrame(render::Frame frame) {
    Image image;
    image.width = frame.width, image.height = frame.height;
    image.channelNames = std::move(frame.channelNames);
    image.storage = PixelType::Float;
    image.pixels = std::move(frame.pixels);
    return image;
}

// Channels [first, first + count) of a frame as their own interleaved buffer, times `scale`, and
// sRGB-encoded (clamped to [0, 1]) if asked: what the display-referred filters read.
inline std::vector<float> frameChannels(const render::Frame& frame, int first, int count, bool encodeSrgb,
                                        float scale = 1.0f) {
    const size_t pixels = size_t(frame.width) * size_t(frame.height);
    std::vector<float> out(pixels * size_t(count));
    for (size_t p = 0; p < pixels; ++p)
        for (int c = 0; c < count; ++c) {
            const float v = frame.pixels[p * size_t(frame.channels()) + size_t(first + c)] * scale;
            out[p * size_t(count) + size_t(c)] =
                encodeSrgb ? std::clamp(linearToSrgb(std::max(v, 0.0f)), 0.0f, 1.0f) : v;
        }
    return out;
}

// A frame rendered once a pixel with its depth and IDs, and its accumulated truth: what scoring a method
// on a rendered frame needs (sRGB-encoded RGB of each, the buffers as an image with id.ID and depth.Z).
struct RenderedPair {
    std::vector<float> aliased, truth;
    Image buffers;
};
inline RenderedPair renderPair(render::Renderer& renderer, int truthSamples, bool adaptive) {
    render::FrameRequest request;
    request.buffers = render::BufferSet::parse("color,depth,id");
    render::Frame frame = renderer.render(request);
    render::TruthOptions options;
    options.samples = truthSamples, options.adaptive = adaptive;
    RenderedPair pair;
    pair.aliased = frameChannels(frame, 0, 3, true);
    pair.truth = frameChannels(renderer.renderTruth(0, options), 0, 3, true);
    pair.buffers = imageFromFrame(std::move(frame));
    return pair;
}

}  // namespace dejag
