// An engine's view of dejag: a frame in memory, anti-aliased by a method chosen by name. Draws a slanted
// edge (the aliasing every method exists for), filters it with FXAA, SMAA and the shipped network, and
// prints how much each changed the frame and how long it took.
//
//   filter_frame [METHOD ...]        (default: fxaa smaa cnn)
#include <dejag/dejag.h>

#include <cmath>
#include <cstdio>
#include <vector>

int main(int argc, char** argv) {
    const int width = 320, height = 180;
    std::vector<float> frame(size_t(width) * height * 3), out(frame.size());
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            for (int c = 0; c < 3; ++c)  // a hard edge at a slant: one sample per pixel, no AA
                frame[(size_t(y) * width + x) * 3 + c] = x * 7 > y * 11 + 200 ? 0.9f : 0.1f;

    std::vector<std::string> methods(argv + 1, argv + argc);
    if (methods.empty()) methods = {"fxaa", "smaa", "cnn"};
    std::printf("dejag %s\n", dejag::api::version().c_str());
    try {
        for (const std::string& method : methods) {
            dejag::api::Filter filter(method);
            filter.setColour(frame.data(), width, height);
            filter.execute(out.data());
            double changed = 0;
            for (size_t i = 0; i < out.size(); ++i) changed += std::abs(out[i] - frame[i]);
            std::printf("%-6s changed %.1f (sum of |out - in|) in %.2f ms\n", method.c_str(), changed,
                        filter.lastMilliseconds());
        }
    } catch (const dejag::api::Error& e) {
        std::fprintf(stderr, "filter_frame: %s\n", e.what());
        return 2;
    }
    return 0;
}
