// dejag: the anti-aliasing filters as a library an engine links (libdejag, `find_package(dejag)` or
// `pkg-config dejag`). One face for every method, after Open Image Denoise's filter object: make a filter
// by name, hand it a frame (its colour and the buffers the method reads), execute.
//
//   dejag::api::Filter filter("cnn", {{"model", "dejag-fast"}});
//   filter.setColour(rgb, width, height);          // sRGB-encoded, [0, 1], interleaved RGB
//   filter.execute(out);                           // the same layout
//
// Images are float32, interleaved (height x width x channels), rows packed. Colour is display-referred
// (sRGB-encoded values in [0, 1]), as every method works on it. The buffers a method needs (the TAAs and
// the temporal network: depth and motion; T-TAA also albedo, id and the previous frame's depth) are set
// per frame; needs() names them. Errors (an unknown method or parameter, a missing buffer, a model file
// that is missing or corrupt) throw dejag::api::Error with one line saying what is wrong.
//
// This header depends on the C++ standard library only. docs/library.md has the reference.
#pragma once

#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#if defined(DEJAG_LIBRARY_BUILD)
#define DEJAG_API __attribute__((visibility("default")))
#else
#define DEJAG_API
#endif

namespace dejag::api {

class DEJAG_API Error : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// The library's version ("0.1.0").
DEJAG_API std::string version();

// Every method a Filter can be made of, with a line of summary each ("fxaa": "FXAA 3.11 ...").
struct MethodInfo {
    std::string name, summary;
    std::vector<std::string> needs;       // buffers it cannot run without
    std::vector<std::string> parameters;  // the parameter names it reads
    bool temporal = false;                // keeps a history across frames
};
DEJAG_API std::vector<MethodInfo> methods();

class DEJAG_API Filter {
  public:
    // method: "none", "fxaa", "smaa", "cnn", "taa", "taa-sobel", "taa-hq", "cnn-temporal", or a chain
    // such as "fxaa,cnn". parameters: as `dejag filter --set NAME=VALUE` takes them, e.g. {"preset", "12"},
    // {"model", "dejag-guided"} (a shipped model's name, found beside the installed library, or a path).
    // A parameter no method of the chain reads is an error, as is a value out of range.
    explicit Filter(const std::string& method, const std::map<std::string, std::string>& parameters = {});
    ~Filter();
    Filter(Filter&&) noexcept;
    Filter& operator=(Filter&&) noexcept;

    // The frame's colour: width x height x channels floats (R, G, B first; further channels, such as
    // alpha, pass through). The data is read at execute(), not copied: keep it alive until then.
    void setColour(const float* colour, int width, int height, int channels = 3);
    // A buffer of the same size: "albedo" (3 channels), "depth" (1, divided by the far plane, so [0, 1]),
    // "motion" (2: pixels moved since the previous frame, x right, y down), "id" (1), "prevdepth" (1).
    // nullptr unsets it. Read at execute().
    void setBuffer(const std::string& name, const float* data);
    // The frame's sub-pixel jitter in pixels (a TAA's camera offset), if the renderer jitters.
    void setJitter(float x, float y);
    // Filters the frame into out (width x height x channels floats, the colour's layout). Allocates only
    // when the frame is larger than any before.
    void execute(float* out);
    // Starts a new history (a camera cut); a method without one ignores it.
    void reset();

    const std::string& method() const;
    std::vector<std::string> needs() const;  // the buffers execute() will ask for
    bool temporal() const;
    double lastMilliseconds() const;  // wall time of the last execute()

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace dejag::api
