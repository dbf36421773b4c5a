// dejag/data: a rendered frame (render::Frame) as an Image, float storage, moving its pixels.
#pragma once

#include <utility>

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

}  // namespace dejag
