#include "infer/frame.h"

#include <algorithm>
#include <cmath>

#include "base/error.h"
#include "base/thread_pool.h"

namespace dejag::infer {

const char* bufferName(Buffer buffer) {
    switch (buffer) {
        case Buffer::Albedo:
            return "albedo";
        case Buffer::Depth:
            return "depth";
        case Buffer::Motion:
            return "motion";
        case Buffer::Ids:
            return "id";
        case Buffer::PreviousDepth:
            return "prevdepth";
        case Buffer::Jitter:
            return "jitter";
    }
    return "?";
}

std::string bufferList(BufferSet set) {
    std::string text;
    for (Buffer b : kBuffers)
        if (contains(set, b)) text += (text.empty() ? "" : ", ") + std::string(bufferName(b));
    return text.empty() ? "none" : text;
}

bool Frame::has(Buffer buffer) const {
    switch (buffer) {
        case Buffer::Albedo:
            return albedo != nullptr;
        case Buffer::Depth:
            return depth != nullptr;
        case Buffer::Motion:
            return motion != nullptr;
        case Buffer::Ids:
            return ids != nullptr;
        case Buffer::PreviousDepth:
            return previousDepth != nullptr;
        case Buffer::Jitter:
            return hasJitter;
    }
    return false;
}

namespace {

size_t bufferIndex(Buffer buffer) {
    switch (buffer) {
        case Buffer::Albedo:
            return 0;
        case Buffer::Depth:
            return 1;
        case Buffer::Motion:
            return 2;
        case Buffer::Ids:
            return 3;
        case Buffer::PreviousDepth:
            return 4;
        case Buffer::Jitter:
            break;
    }
    throw Error("the jitter is not read from channels");
}

size_t channelCount(Buffer buffer) {
    switch (buffer) {
        case Buffer::Albedo:
            return 3;
        case Buffer::Motion:
            return 2;
        default:
            return 1;
    }
}

}  // namespace

std::vector<std::string> splitFields(const std::string& text) {
    std::vector<std::string> fields;
    size_t start = 0;
    while (true) {
        const size_t comma = text.find(',', start);
        fields.push_back(text.substr(start, comma - start));
        if (comma == std::string::npos) break;
        start = comma + 1;
    }
    return fields;
}

ChannelMap::ChannelMap() {
    buffers[0] = {"albedo.R", "albedo.G", "albedo.B"};
    buffers[1] = {"depth.Z"};
    buffers[2] = {"motion.X", "motion.Y"};
    buffers[3] = {"id.ID"};
    buffers[4] = {"prevdepth.Z"};
}

ChannelMap ChannelMap::preset(const std::string& name) {
    ChannelMap map;
    if (name == "dejag") return map;
    if (name != "blender") throw Error("--channels '" + name + "' is not dejag or blender");
    // Blender's multilayer EXR: "VIEWLAYER.PASS.COMPONENT". Its Vector pass holds the motion to the
    // previous frame's position in X, Y (pixels, y up): the motion since then is its negation in x and
    // the value itself in y once y points down. Blender has no previous-depth pass.
    const std::string layer = "ViewLayer.";
    map.colour = {layer + "Combined.R", layer + "Combined.G", layer + "Combined.B"};
    map.buffers[0] = {layer + "DiffCol.R", layer + "DiffCol.G", layer + "DiffCol.B"};
    map.buffers[1] = {layer + "Depth.Z"};
    map.buffers[2] = {"-" + layer + "Vector.X", layer + "Vector.Y"};
    map.buffers[3] = {layer + "IndexOB.X"};
    map.buffers[4] = {layer + "PrevDepth.Z"};
    return map;
}

void ChannelMap::assign(const std::string& assignment) {
    const size_t equals = assignment.find('=');
    const std::string bad = "--channel '" + assignment + "' is not BUFFER=NAME[,NAME...] (e.g. depth=Z)";
    if (equals == std::string::npos || equals == 0 || equals + 1 == assignment.size()) throw Error(bad);
    const std::string buffer = assignment.substr(0, equals);
    const std::vector<std::string> names = splitFields(assignment.substr(equals + 1));
    for (const std::string& n : names)
        if (n.empty() || n == "-") throw Error(bad + ": an empty channel name");
    if (buffer == "color" || buffer == "colour") {
        if (names.size() != 3) throw Error(bad + ": color takes 3 channels (R,G,B)");
        colour = names;
        return;
    }
    for (Buffer b : kBuffers) {
        if (b == Buffer::Jitter || buffer != bufferName(b)) continue;
        if (names.size() != channelCount(b))
            throw Error(bad + ": " + buffer + " takes " + std::to_string(channelCount(b)) + " channel" +
                        (channelCount(b) == 1 ? "" : "s"));
        buffers[bufferIndex(b)] = names;
        return;
    }
    throw Error(bad + ": the buffers are color, albedo, depth, motion, id, prevdepth");
}

const std::vector<std::string>& ChannelMap::namesOf(Buffer buffer) const {
    return buffers[bufferIndex(buffer)];
}

Frame FrameData::frame() const {
    Frame f;
    f.width = width, f.height = height;
    f.channels = int(colourNames.size());
    f.colour = colour.data();
    auto view = [](const std::vector<float>& v) { return v.empty() ? nullptr : v.data(); };
    f.albedo = view(albedo), f.depth = view(depth), f.motion = view(motion), f.ids = view(ids);
    f.previousDepth = view(previousDepth);
    f.hasJitter = hasJitter, f.jitter[0] = jitter[0], f.jitter[1] = jitter[1];
    return f;
}

namespace {

struct Lookup {
    std::vector<int> index;
    std::vector<float> sign;
};

// The channel indices of `names` in the image, or empty if one is absent (*missing names it).
Lookup lookUp(const Image& image, const std::vector<std::string>& names, std::string* missing) {
    Lookup found;
    for (const std::string& name : names) {
        const bool negate = !name.empty() && name[0] == '-';
        const std::string plain = negate ? name.substr(1) : name;
        const int c = image.findChannel(plain);
        if (c < 0) {
            if (missing) *missing = plain;
            return {};
        }
        found.index.push_back(c);
        found.sign.push_back(negate ? -1.0f : 1.0f);
    }
    return found;
}

// Gathers the channels into a (pixels, k) plane: encode turns linear light into sRGB in [0, 1], divisor
// divides (depth / far, in double). On the thread pool; each value on its own.
std::vector<float> gather(const Image& image, const Lookup& lookup, bool encode, double divisor) {
    const size_t k = lookup.index.size(), C = size_t(image.channels());
    std::vector<float> out(image.pixelCount() * k);
    parallelFor(0, int64_t(image.pixelCount()), 1 << 14, [&](int64_t first, int64_t last) {
        for (size_t p = size_t(first); p < size_t(last); ++p)
            for (size_t j = 0; j < k; ++j) {
                float v = image.pixels[p * C + size_t(lookup.index[j])] * lookup.sign[j];
                if (encode) v = std::clamp(linearToSrgb(std::max(v, 0.0f)), 0.0f, 1.0f);
                out[p * k + j] = divisor == 1.0 ? v : float(v / divisor);
            }
    });
    return out;
}

}  // namespace

FrameData frameFromImage(const Image& image, const FrameOptions& options, const std::string& path) {
    FrameData data;
    data.width = image.width, data.height = image.height;
    const bool linear = holdsLinearLight(image.storage);
    std::string missing;
    Lookup colour = lookUp(image, options.channels.colour, &missing);
    if (colour.index.empty())
        throw Error("'" + path + "' has no colour channel " + missing + " (" + image.describe() +
                    "; name the colour channels with --channel color=R,G,B)");
    // The colour kept: the file's first three channels R G B and every channel after them, or the three
    // named channels and an alpha beside them.
    const bool firstThree =
        colour.index == std::vector<int>{0, 1, 2} && colour.sign == std::vector<float>(3, 1.0f);
    if (firstThree && options.keepExtraChannels) {
        for (int c = 3; c < image.channels(); ++c) colour.index.push_back(c), colour.sign.push_back(1.0f);
    } else {
        const std::string& red = options.channels.colour[0];
        const size_t dot = red.rfind('.');
        const std::string alpha = dot == std::string::npos ? "A" : red.substr(0, dot + 1) + "A";
        if (const int a = image.findChannel(alpha); a >= 0)
            colour.index.push_back(a), colour.sign.push_back(1.0f);
    }
    for (int c : colour.index) data.colourNames.push_back(image.channelNames[size_t(c)]);
    // Only R G B are encoded; alpha and other layers keep their values.
    data.colour = gather(image, colour, false, 1.0);
    if (linear) {
        const size_t k = colour.index.size();
        parallelFor(0, int64_t(image.pixelCount()), 1 << 14, [&](int64_t first, int64_t last) {
            for (size_t p = size_t(first); p < size_t(last); ++p)
                for (size_t j = 0; j < 3; ++j) {
                    float& v = data.colour[p * k + j];
                    v = std::clamp(linearToSrgb(std::max(v, 0.0f)), 0.0f, 1.0f);
                }
        });
    }
    const double far = options.depthFar > 0 ? options.depthFar : 1.0;
    for (Buffer b : kBuffers) {
        if (b == Buffer::Jitter || !contains(options.wanted | options.required, b)) continue;
        const Lookup found = lookUp(image, options.channels.namesOf(b), &missing);
        if (found.index.empty()) {
            if (contains(options.required, b))
                throw Error(
                    "'" + path + "' has no channel " + missing + " for the " + bufferName(b) +
                    " buffer (name it with --channel " + bufferName(b) +
                    "=NAME; dejag render writes it with --buffers color,albedo,depth,motion,id,prevdepth)");
            continue;
        }
        switch (b) {
            case Buffer::Albedo:
                data.albedo = gather(image, found, linear, 1.0);
                break;
            case Buffer::Depth:
                data.depth = gather(image, found, false, far);
                break;
            case Buffer::Motion:
                data.motion = gather(image, found, false, 1.0);
                break;
            case Buffer::Ids:
                data.ids = gather(image, found, false, 1.0);
                break;
            case Buffer::PreviousDepth:
                data.previousDepth = gather(image, found, false, far);
                break;
            case Buffer::Jitter:
                break;
        }
    }
    return data;
}

double largestFiniteDepth(const Image& image, const ChannelMap& channels) {
    std::string missing;
    const Lookup found = lookUp(image, channels.namesOf(Buffer::Depth), &missing);
    if (found.index.empty()) return 0;
    const size_t C = size_t(image.channels()), c = size_t(found.index[0]);
    double largest = 0;
    for (size_t p = 0; p < image.pixelCount(); ++p) {
        const double d = std::abs(double(image.pixels[p * C + c]));
        if (std::isfinite(d) && d < 1e9) largest = std::max(largest, d);
    }
    return largest;
}

const float* RgbScratch::rgb(const Frame& frame) {
    const size_t pixels = size_t(frame.width) * size_t(frame.height), C = size_t(frame.channels);
    if (C == 3) return frame.colour;
    rgb_.resize(pixels * 3);
    parallelFor(0, int64_t(pixels), 1 << 14, [&](int64_t first, int64_t last) {
        for (size_t p = size_t(first); p < size_t(last); ++p)
            for (size_t c = 0; c < 3; ++c) rgb_[p * 3 + c] = frame.colour[p * C + c];
    });
    return rgb_.data();
}

float* RgbScratch::result(const Frame& frame, float* out) {
    if (frame.channels == 3) return out;
    result_.resize(size_t(frame.width) * size_t(frame.height) * 3);
    return result_.data();
}

void RgbScratch::finish(const Frame& frame, float* out) {
    const size_t pixels = size_t(frame.width) * size_t(frame.height), C = size_t(frame.channels);
    if (C == 3) return;
    parallelFor(0, int64_t(pixels), 1 << 14, [&](int64_t first, int64_t last) {
        for (size_t p = size_t(first); p < size_t(last); ++p)
            for (size_t c = 0; c < C; ++c)
                out[p * C + c] = c < 3 ? result_[p * 3 + c] : frame.colour[p * C + c];
    });
}

}  // namespace dejag::infer
