// dejag view: a scene animated along its camera path in a window, anti-aliased live by any method, beside
// another method or alone; keys switch methods and scenes, pause, step and reset the history; a script of
// key presses and a screenshot make it testable under a virtual display (docs/view.md).
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include <nlohmann/json.hpp>

#include "app/cli.h"
#include "app/commands.h"
#include "base/error.h"
#include "base/timer.h"
#include "data/frame_image.h"
#include "data/image.h"
#include "infer/filter.h"
#include "infer/glsl_filter.h"
#include "render/halton.h"
#include "render/renderer.h"
#include "render/scene.h"
#include "render/text.h"
#include "render/window.h"

namespace dejag::cli {
namespace {

// The methods the number keys select, in order (1 .. 8).
const char* const kMethods[] = {"none", "fxaa", "smaa", "taa", "taa-sobel", "taa-hq", "cnn", "cnn-temporal"};

struct ViewArguments {
    std::string scene = "pipe", method = "fxaa", compare, size = "960x540", script, screenshot,
                mode = "split", device = "auto";
    int frames = 0;  // 0: until the window closes
    int truthSamples = 64;
    bool json = false, noOverlay = false;
    std::string model, temporalModel;  // the networks of keys 7 and 8 ("": the shipped defaults)
    float spread = 1.7f;
    RuntimeOptions runtime;
};

// A scripted key press: at frame `frame`, the key named (1-8, shift+1-8, space, n, r, c, f, z, t, g, o,
// tab, q).
struct ScriptedKey {
    int frame = 0;
    int key = 0, mods = 0;
};

int keyCode(const std::string& name, int* mods) {
    *mods = 0;
    std::string k = name;
    if (k.rfind("shift+", 0) == 0) *mods = GLFW_MOD_SHIFT, k = k.substr(6);
    if (k.size() == 1 && k[0] >= '1' && k[0] <= '9') return GLFW_KEY_1 + (k[0] - '1');
    static const std::map<std::string, int> named = {
        {"space", GLFW_KEY_SPACE}, {"n", GLFW_KEY_N},     {"r", GLFW_KEY_R}, {"c", GLFW_KEY_C},
        {"f", GLFW_KEY_F},         {"z", GLFW_KEY_Z},     {"t", GLFW_KEY_T}, {"g", GLFW_KEY_G},
        {"o", GLFW_KEY_O},         {"tab", GLFW_KEY_TAB}, {"q", GLFW_KEY_Q}, {"escape", GLFW_KEY_ESCAPE}};
    if (auto it = named.find(k); it != named.end()) return it->second;
    return -1;
}

std::vector<ScriptedKey> readScript(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw Error("cannot read the script '" + path + "'");
    std::vector<ScriptedKey> keys;
    std::string line;
    for (int number = 1; std::getline(in, line); ++number) {
        if (const size_t hash = line.find('#'); hash != std::string::npos) line.resize(hash);
        std::istringstream fields(line);
        std::string frame, key;
        if (!(fields >> frame)) continue;
        ScriptedKey k;
        char* end = nullptr;
        k.frame = int(std::strtol(frame.c_str(), &end, 10));
        if (!(fields >> key) || !end || *end || k.frame < 0 || (k.key = keyCode(key, &k.mods)) < 0)
            throw Error(
                "script '" + path + "', line " + std::to_string(number) +
                ": expected FRAME KEY (a key: 1-8, shift+1-8, space, n, r, c, f, z, t, g, o, tab, q)");
        keys.push_back(k);
    }
    return keys;
}

constexpr const char* kVertexShader = R"(#version 330 core
out vec2 uv;
void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    uv = vec2(p.x, 1.0 - p.y);
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
})";

// Two images side by side at a split (0..1 of the width; 1: A alone), and a lens: the region around
// `lens.xy` (0..1), as split, magnified 4x into the top right corner when lens.z > 0. Nearest texels.
constexpr const char* kFragmentShader = R"(#version 330 core
in vec2 uv;
out vec4 colour;
uniform sampler2D imageA;
uniform sampler2D imageB;
uniform float split;
uniform vec3 lens;
uniform sampler2D overlay;  // the text's coverage
uniform vec4 overlayRect;   // its place: left, top, right, bottom (0..1); empty: no overlay
vec3 at(vec2 p) { return p.x < split ? texture(imageA, p).rgb : texture(imageB, p).rgb; }
void main() {
    vec2 p = uv;
    if (lens.z > 0.0 && uv.x > 0.7 && uv.y < 0.3) {
        p = lens.xy + (uv - vec2(0.85, 0.15)) / 4.0;
        colour = vec4(at(p), 1.0);
        if (abs(uv.x - 0.7) < 0.003 || abs(uv.y - 0.3) < 0.004) colour = vec4(1.0, 0.2, 0.2, 1.0);
    } else {
        colour = vec4(at(p), 1.0);
        if (split > 0.0 && split < 1.0 && abs(uv.x - split) < 0.0015) colour = vec4(1.0, 1.0, 1.0, 1.0);
    }
    if (uv.x >= overlayRect.x && uv.x < overlayRect.z && uv.y >= overlayRect.y && uv.y < overlayRect.w) {
        float coverage = texture(overlay, (uv - overlayRect.xy) / (overlayRect.zw - overlayRect.xy)).r;
        colour.rgb = mix(colour.rgb * 0.35, vec3(1.0), coverage);
    }
})";

class Viewer {
  public:
    explicit Viewer(const ViewArguments& args) : args_(args) {
        const Size size = parseSize(args.size, "--size");
        width_ = size.width, height_ = size.height;
        method_[0] = methodIndex(args.method, "--method");
        method_[1] = args.compare.empty() ? -1 : methodIndex(args.compare, "--compare");
        if (args.mode != "split" && args.mode != "flip")
            throw Error("--mode is split or flip, not '" + args.mode + "'");
        if (args.device != "auto" && args.device != "gpu" && args.device != "cpu")
            throw Error("--device is auto, gpu or cpu, not '" + args.device + "'");
        flip_ = args.mode == "flip";
        overlay_ = !args.noOverlay;
        for (const render::SceneInfo& info : render::sceneCatalogue()) scenes_.push_back(info.name);
        sceneIndex_ = int(std::find(scenes_.begin(), scenes_.end(), args.scene) - scenes_.begin());
        if (sceneIndex_ >= int(scenes_.size())) render::buildScene(args.scene);  // unknown: its one line
        if (!args.script.empty()) script_ = readScript(args.script);
        window_ = render::Window::open(width_, height_, "dejag view");
        window_->onKey([this](int key, int mods) { press(key, mods); });
        gpuDevice_ = args.device != "cpu";
        if (gpuDevice_) setUpGpu();
        setUpDisplay();
        buildScene();
    }

    ~Viewer() {
        if (!window_) return;
        const render::GlFunctions& gl = window_->gl();
        gl.DeleteTextures(2, textures_);
        gl.DeleteTextures(1, &overlayTexture_);
        gl.DeleteVertexArrays(1, &vertexArray_);
        gl.DeleteProgram(program_);
    }

    void run() {
        while (!window_->shouldClose()) {
            for (const ScriptedKey& k : script_)
                if (k.frame == shown_) press(k.key, k.mods);
            if (!paused_ || step_) advance();
            step_ = false;
            draw();
            window_->swapBuffers();
            window_->pollEvents();
            ++shown_;
            if (args_.frames > 0 && shown_ >= args_.frames) break;
        }
        if (!args_.screenshot.empty()) screenshot(args_.screenshot);
        summarise();
    }

  private:
    static int methodIndex(const std::string& name, const std::string& flag) {
        for (int i = 0; i < int(std::size(kMethods)); ++i)
            if (name == kMethods[i]) return i;
        std::string known;
        for (const char* m : kMethods) known += (known.empty() ? "" : ", ") + std::string(m);
        throw Error(flag + " '" + name + "' is not a method the viewer runs (" + known + ")");
    }

    // The GPU path needs compute shaders (OpenGL 4.3); without them `auto` runs every method on the CPU.
    void setUpGpu() {
        try {
            window_->compute();
        } catch (const Error& e) {
            if (args_.device == "gpu") throw Error("--device gpu: " + std::string(e.what()));
            gpuDevice_ = false;
            return;
        }
        import_ = std::make_unique<infer::GlslFrameImport>(*window_);
        for (auto& b : outputGpu_) b = std::make_unique<infer::GlslBuffer>(*window_);
        const std::string description = window_->description();
        emulated_ = description.find("llvmpipe") != std::string::npos ||
                    description.find("softpipe") != std::string::npos;
        // Where OpenGL runs on the CPU, dejag's own CPU filters are the fast path: auto starts there (key g
        // switches; --device gpu insists).
        if (emulated_ && args_.device == "auto") gpuDevice_ = false;
    }

    void buildScene() {
        scene_ = std::make_unique<render::Scene>(render::buildScene(scenes_[size_t(sceneIndex_)]));
        renderer_ = std::make_unique<render::Renderer>(*window_, *scene_, width_, height_);
        time_ = 0;
        showTruth_ = false;
        makeFilters();
    }

    // Each side's method: its GPU form where the device allows and the method has one, else the CPU filter.
    void makeFilters() {
        for (int k = 0; k < 2; ++k) {
            filters_[k].reset(), gpuFilters_[k].reset();
            whyCpu_[k].clear();
            if (method_[k] < 0) continue;
            const std::string method = kMethods[method_[k]];
            infer::FilterParameters parameters;
            parameters.setPathResolver(shippedModelPath);  // the shipped networks, from any folder
            if (method == "cnn" && !args_.model.empty()) parameters.set("model", args_.model, "--model");
            if (method == "cnn-temporal" && !args_.temporalModel.empty())
                parameters.set("model", args_.temporalModel, "--temporal-model");
            if (gpuDevice_) gpuFilters_[k] = infer::makeGlslFilter(*window_, method, parameters, &whyCpu_[k]);
            if (!gpuDevice_) whyCpu_[k] = "--device cpu";
            if (!gpuFilters_[k] && args_.device == "gpu")
                throw Error("--device gpu: " + (whyCpu_[k].empty() ? method : whyCpu_[k]));
            if (!gpuFilters_[k]) filters_[k] = infer::makeFilter(method, parameters);
        }
    }

    void press(int key, int mods) {
        if (key >= GLFW_KEY_1 && key <= GLFW_KEY_8) {
            method_[(mods & GLFW_MOD_SHIFT) ? 1 : 0] = key - GLFW_KEY_1;
            if (mods & GLFW_MOD_SHIFT) showTruth_ = false;
            makeFilters();
            // The frame on screen is filtered again by the new method.
            if (haveFrame_) renderAndFilter(time_ - 1);
        } else if (key == GLFW_KEY_SPACE) {
            paused_ = !paused_;
            if (!paused_) showTruth_ = false;  // the truth was of the paused pose
        } else if (key == GLFW_KEY_N) {
            step_ = true;
            showTruth_ = false;
        } else if (key == GLFW_KEY_R) {
            for (auto& f : filters_)
                if (f) f->reset();
            for (auto& f : gpuFilters_)
                if (f) f->reset();
        } else if (key == GLFW_KEY_C) {
            flip_ = !flip_;
        } else if (key == GLFW_KEY_F) {
            showB_ = !showB_;
        } else if (key == GLFW_KEY_Z) {
            lens_ = !lens_;
        } else if (key == GLFW_KEY_O) {
            overlay_ = !overlay_;
        } else if (key == GLFW_KEY_T) {
            if (paused_ && haveFrame_ && !showTruth_)
                accumulateTruth();
            else
                showTruth_ = false;
        } else if (key == GLFW_KEY_G) {
            if (args_.device == "auto" && import_) {
                gpuDevice_ = !gpuDevice_;
                makeFilters();
                if (haveFrame_) renderAndFilter(time_ - 1);
            }
        } else if (key == GLFW_KEY_TAB) {
            sceneIndex_ = (sceneIndex_ + 1) % int(scenes_.size());
            buildScene();
        } else if (key == GLFW_KEY_Q || key == GLFW_KEY_ESCAPE) {
            window_->close();
        }
    }

    // The next frame of the camera path.
    void advance() {
        renderAndFilter(time_);
        ++time_;
    }

    // Frame `time` of the camera path, jittered for the TAAs, with every buffer the CPU methods read; the
    // frame is read back only if a method runs on the CPU.
    void renderAndFilter(int time) {
        const bool cpu = (method_[0] >= 0 && !gpuFilters_[0]) || (method_[1] >= 0 && !gpuFilters_[1]);
        // The buffers the GPU forms read, besides the colour.
        infer::BufferSet gpuWanted = 0;
        for (int k = 0; k < 2; ++k)
            if (gpuFilters_[k]) {
                const infer::MethodSpec* spec = infer::findMethod(kMethods[method_[k]]);
                gpuWanted |= spec->needs | spec->optional;
            }
        render::FrameRequest request;
        request.time = double(time);
        request.previousTime = double(time - 1);
        request.jitter = render::jitterPixels(unsigned(time % 16), args_.spread);
        request.previousJitter = render::jitterPixels(unsigned((time + 15) % 16), args_.spread);
        request.buffers = cpu || gpuWanted ? render::BufferSet::all() : render::BufferSet{};
        request.readBack = cpu;
        Stopwatch clock;
        const render::Frame frame = renderer_->render(request);
        renderMs_ = clock.elapsedMs();
        haveFrame_ = true;
        if (cpu) {
            infer::FrameOptions options;
            options.wanted = infer::Buffer::Albedo | infer::Buffer::Depth | infer::Buffer::Motion |
                             infer::Buffer::Ids | infer::Buffer::PreviousDepth;
            options.depthFar = scene_->far;
            options.keepExtraChannels = false;  // the colour alone (R, G, B, and A if the frame has one)
            data_ = infer::frameFromImage(imageFromFrame(frame), options, "frame " + std::to_string(time));
            data_.hasJitter = true, data_.jitter[0] = float(request.jitter.x),
            data_.jitter[1] = float(-request.jitter.y);
        }
        infer::GlslFrame gpuFrame;
        if (gpuFilters_[0] || gpuFilters_[1]) {
            gpuFrame = import_->run(renderer_->textures(), width_, height_, gpuWanted, float(scene_->far));
            gpuFrame.hasJitter = true, gpuFrame.jitter[0] = float(request.jitter.x),
            gpuFrame.jitter[1] = float(-request.jitter.y);
        }
        for (int k = 0; k < 2; ++k) {
            if (gpuFilters_[k]) {
                const render::GlFunctions& gl = window_->compute();
                const unsigned out = outputGpu_[k]->ensure(size_t(width_) * size_t(height_) * 3);
                // Each pass timed (a timer query; on llvmpipe, which does a dispatch's work after the
                // query has ended, the wall time between glFinish calls); the method's time their sum.
                render::PassTimer timer;
                timer.wallClock = emulated_;
                window_->passTimer = &timer;
                gpuFilters_[k]->run(gpuFrame, out);
                window_->passTimer = nullptr;
                const std::pair<std::string, std::string> key = {kMethods[method_[k]],
                                                                 emulated_ ? "gpu (emulated)" : "gpu"};
                filterMs_[k] = 0;
                auto& passes = passTimes_[key];
                for (size_t i = 0; i < timer.passes.size(); ++i) {
                    filterMs_[k] += timer.passes[i].second;
                    if (passes.size() <= i) passes.push_back({timer.passes[i].first, {}});
                    passes[i].second.push_back(timer.passes[i].second);
                }
                times_[key].push_back(filterMs_[k]);
                // Into the displayed texture on the GPU: the buffer is the texture's pixel source.
                gl.MemoryBarrier(GL_PIXEL_BUFFER_BARRIER_BIT);
                gl.BindBuffer(GL_PIXEL_UNPACK_BUFFER, out);
                gl.BindTexture(GL_TEXTURE_2D, textures_[k]);
                gl.PixelStorei(GL_UNPACK_ALIGNMENT, 4);
                gl.TexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, width_, height_, 0, GL_RGB, GL_FLOAT, nullptr);
                gl.BindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
            } else if (filters_[k]) {
                outputs_[k].resize(data_.colour.size());
                filters_[k]->apply(data_.frame(), outputs_[k].data());
                filterMs_[k] = filters_[k]->figures().ms;
                times_[{kMethods[method_[k]], "cpu"}].push_back(filterMs_[k]);
                upload(textures_[k], outputs_[k], data_.colourNames.size() == 4);
            }
        }
        if (const GLenum error = window_->gl().GetError(); error != GL_NO_ERROR)
            throw Error("dejag view: OpenGL error " + std::to_string(error) + " while filtering");
    }

    // The supersampled truth of the pose on screen (the box filter over each pixel, as dejag render
    // --truth makes it), shown in place of the compared method until the view moves on.
    void accumulateTruth() {
        render::TruthOptions options;
        options.samples = args_.truthSamples;
        Stopwatch clock;
        const render::Frame truth = renderer_->renderTruth(double(time_ - 1), options);
        truthMs_ = clock.elapsedMs();
        upload(textures_[1], frameChannels(truth, 0, 3, true), false);
        showTruth_ = true;
    }

    void setUpDisplay() {
        const render::GlFunctions& gl = window_->gl();
        program_ = render::compileProgram(
            gl, {{GL_VERTEX_SHADER, kVertexShader}, {GL_FRAGMENT_SHADER, kFragmentShader}},
            "the viewer's display program");
        gl.GenVertexArrays(1, &vertexArray_);
        gl.GenTextures(2, textures_);
        gl.GenTextures(1, &overlayTexture_);
        for (GLuint t : {textures_[0], textures_[1], overlayTexture_}) {
            gl.BindTexture(GL_TEXTURE_2D, t);
            gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
            gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
            gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
            gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
        }
    }

    void upload(GLuint texture, const std::vector<float>& rgb, bool alpha) {
        const render::GlFunctions& gl = window_->gl();
        gl.BindTexture(GL_TEXTURE_2D, texture);
        gl.PixelStorei(GL_UNPACK_ALIGNMENT, 4);
        gl.TexImage2D(GL_TEXTURE_2D, 0, alpha ? GL_RGBA32F : GL_RGB32F, width_, height_, 0,
                      alpha ? GL_RGBA : GL_RGB, GL_FLOAT, rgb.data());
    }

    // "fxaa 1.2 ms gpu": a side's method, its last time and where it ran.
    std::string describe(int k) const {
        char text[160];
        if (k == 1 && showTruth_) {
            std::snprintf(text, sizeof text, "truth (%d samples, %.0f ms)", args_.truthSamples, truthMs_);
            return text;
        }
        std::snprintf(text, sizeof text, "%s %.1f ms %s", kMethods[method_[k]], filterMs_[k],
                      gpuFilters_[k] ? (emulated_ ? "gpu (emulated)" : "gpu") : "cpu");
        return text;
    }

    void draw() {
        const render::GlFunctions& gl = window_->gl();
        if (!haveFrame_) return;
        const bool compare = method_[1] >= 0 || showTruth_;
        // The overlay: what is shown, each method's time and where it ran (GPU timer queries for the GPU
        // passes), the render time and the rate; in the title too.
        const double now = fps_.elapsedMs();
        frameMs_ = 0.9 * frameMs_ + 0.1 * (now - lastFrame_);
        lastFrame_ = now;
        std::vector<std::string> lines = {scenes_[size_t(sceneIndex_)] + "  frame " +
                                              std::to_string(time_ - 1) + (paused_ ? " (paused)" : ""),
                                          "A: " + describe(0)};
        if (compare)
            lines.push_back("B: " + describe(1) + (flip_ ? (showB_ ? " [shown]" : " [hidden]") : ""));
        char tail[96];
        std::snprintf(tail, sizeof tail, "render %.1f ms  %.0f fps", renderMs_,
                      frameMs_ > 0 ? 1000.0 / frameMs_ : 0.0);
        lines.push_back(tail);
        std::string title = "dejag view";
        for (const std::string& line : lines) title += "  " + line;
        window_->setTitle(title);
        int fw = 0, fh = 0;
        window_->framebufferSize(&fw, &fh);
        float rect[4] = {0, 0, 0, 0};
        if (overlay_) {
            if (!text_) text_ = std::make_unique<render::TextRenderer>(std::clamp(fh / 36, 10, 24));
            const render::TextBitmap bitmap = text_->render(lines);
            gl.BindTexture(GL_TEXTURE_2D, overlayTexture_);
            gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
            gl.TexImage2D(GL_TEXTURE_2D, 0, GL_R8, bitmap.width, bitmap.height, 0, GL_RED, GL_UNSIGNED_BYTE,
                          bitmap.coverage.data());
            rect[0] = 8.0f / float(fw), rect[1] = 8.0f / float(fh);
            rect[2] = rect[0] + float(bitmap.width) / float(fw),
            rect[3] = rect[1] + float(bitmap.height) / float(fh);
        }
        gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
        gl.Viewport(0, 0, fw, fh);
        gl.Disable(GL_DEPTH_TEST);
        gl.UseProgram(program_);
        gl.ActiveTexture(GL_TEXTURE0);
        gl.BindTexture(GL_TEXTURE_2D, textures_[0]);
        gl.ActiveTexture(GL_TEXTURE1);
        gl.BindTexture(GL_TEXTURE_2D, textures_[compare ? 1 : 0]);
        gl.ActiveTexture(GL_TEXTURE2);
        gl.BindTexture(GL_TEXTURE_2D, overlayTexture_);
        gl.ActiveTexture(GL_TEXTURE0);
        gl.Uniform1i(gl.GetUniformLocation(program_, "imageA"), 0);
        gl.Uniform1i(gl.GetUniformLocation(program_, "imageB"), 1);
        gl.Uniform1i(gl.GetUniformLocation(program_, "overlay"), 2);
        gl.Uniform4f(gl.GetUniformLocation(program_, "overlayRect"), rect[0], rect[1], rect[2], rect[3]);
        // Split: A left of the middle, B right; flip: one of them whole (f switches).
        const float split = !compare ? 1.0f : flip_ ? (showB_ ? 0.0f : 1.0f) : 0.5f;
        gl.Uniform1f(gl.GetUniformLocation(program_, "split"), split);
        gl.Uniform3f(gl.GetUniformLocation(program_, "lens"), 0.5f, 0.5f, lens_ ? 1.0f : 0.0f);
        gl.BindVertexArray(vertexArray_);
        gl.DrawArrays(GL_TRIANGLES, 0, 3);
    }

    // At the end, each method's median time per frame and where it ran: a line each, or JSON lines.
    void summarise() const {
        const std::string renderer = window_->description();
        for (const auto& [key, times] : times_) {
            const double ms = median(times);
            if (args_.json) {
                nlohmann::json row = {{"method", key.first}, {"device", key.second}, {"frames", times.size()},
                                      {"median_ms", ms},     {"size", args_.size},   {"opengl", renderer}};
                if (const auto found = passTimes_.find(key); found != passTimes_.end()) {
                    row["passes"] = nlohmann::json::array();
                    for (const auto& [name, passTimes] : found->second)
                        row["passes"].push_back({{"name", name}, {"median_ms", median(passTimes)}});
                }
                std::printf("%s\n", row.dump().c_str());
            } else {
                std::printf("%-13s %-15s %6.2f ms a frame (median of %zu)\n", key.first.c_str(),
                            key.second.c_str(), ms, times.size());
            }
        }
        if (!args_.json && !times_.empty())
            std::printf("OpenGL: %s%s\n", renderer.c_str(),
                        emulated_ ? " (emulated on the CPU: the GPU times are CPU times)" : "");
    }

    void screenshot(const std::string& path) {
        const render::GlFunctions& gl = window_->gl();
        int fw = 0, fh = 0;
        window_->framebufferSize(&fw, &fh);
        std::vector<unsigned char> bytes(size_t(fw) * size_t(fh) * 3);
        gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
        gl.ReadBuffer(GL_BACK);
        gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
        // The back buffer holds the last frame drawn: draw it again there before reading.
        draw();
        gl.ReadPixels(0, 0, fw, fh, GL_RGB, GL_UNSIGNED_BYTE, bytes.data());
        Image image(fw, fh, {"R", "G", "B"}, PixelType::UInt8);
        for (int y = 0; y < fh; ++y)
            for (int x = 0; x < fw * 3; ++x)
                image.pixels[size_t(y) * size_t(fw) * 3 + size_t(x)] =
                    float(bytes[size_t(fh - 1 - y) * size_t(fw) * 3 + size_t(x)]) / 255.0f;
        writeImage(path, image);
    }

    ViewArguments args_;
    int width_ = 0, height_ = 0;
    std::vector<std::string> scenes_;
    int sceneIndex_ = 0, method_[2] = {0, -1};
    std::vector<ScriptedKey> script_;
    std::unique_ptr<render::Window> window_;
    std::unique_ptr<render::Scene> scene_;
    std::unique_ptr<render::Renderer> renderer_;
    // Per side: the CPU filter, or the GPU form and its output buffer; why a side runs on the CPU.
    std::unique_ptr<infer::Filter> filters_[2];
    std::unique_ptr<infer::GlslFilter> gpuFilters_[2];
    std::unique_ptr<infer::GlslBuffer> outputGpu_[2];
    std::string whyCpu_[2];
    std::unique_ptr<infer::GlslFrameImport> import_;
    bool gpuDevice_ = false, emulated_ = false;
    infer::FrameData data_;
    std::vector<float> outputs_[2];
    bool haveFrame_ = false, paused_ = false, step_ = false, flip_ = false, showB_ = false, lens_ = false,
         showTruth_ = false;
    int time_ = 0, shown_ = 0;
    double renderMs_ = 0, filterMs_[2] = {0, 0}, truthMs_ = 0, frameMs_ = 0, lastFrame_ = 0;
    Stopwatch fps_;
    std::map<std::pair<std::string, std::string>, std::vector<double>> times_;  // (method, device) -> ms
    // (method, device) -> each GPU pass's name and times, in dispatch order.
    std::map<std::pair<std::string, std::string>, std::vector<std::pair<std::string, std::vector<double>>>>
        passTimes_;
    GLuint program_ = 0, vertexArray_ = 0, textures_[2] = {0, 0}, overlayTexture_ = 0;
    bool overlay_ = true;
    std::unique_ptr<render::TextRenderer> text_;
};

}  // namespace

void registerViewCommand(CLI::App& app) {
    auto args = std::make_shared<ViewArguments>();
    CLI::App* command = app.add_subcommand(
        "view", "show a scene live in a window, anti-aliased by any method, alone or beside another");
    command->add_option("--scene", args->scene, "the scene (dejag render --list)")->capture_default_str();
    command
        ->add_option("--method", args->method,
                     "the method shown (keys 1-8: none, fxaa, smaa, taa, "
                     "taa-sobel, taa-hq, cnn, cnn-temporal)")
        ->capture_default_str();
    command->add_option("--compare", args->compare, "a second method beside it (shift+1-8)");
    command->add_option("--mode", args->mode, "split (side by side) or flip (one at a time; key f)")
        ->capture_default_str();
    command->add_option("--size", args->size, "window size WIDTHxHEIGHT")->capture_default_str();
    command->add_option("--frames", args->frames, "stop after this many frames (default: when closed)")
        ->check(CLI::Range(0, 1000000));
    command->add_option("--script", args->script, "key presses by frame: lines of FRAME KEY");
    command->add_option("--screenshot", args->screenshot, "write the last frame shown to this PNG");
    command
        ->add_option("--device", args->device,
                     "where the methods run: gpu (their GLSL forms, on the rendered frame), cpu, or auto "
                     "(the GLSL forms on a GPU, the CPU filters where OpenGL is emulated on the CPU; key g "
                     "switches)")
        ->capture_default_str();
    command->add_option("--truth-samples", args->truthSamples, "samples of the truth key t accumulates")
        ->check(CLI::Range(1, 4096))
        ->capture_default_str();
    command->add_flag("--json", args->json, "at the end, each method's median time as a JSON line");
    command->add_flag("--no-overlay", args->noOverlay, "start without the text overlay (key o)");
    command->add_option("--model", args->model,
                        "the single-frame network of key 7 (cnn): a model file or a shipped name (default "
                        "dejag-fast)");
    command->add_option("--temporal-model", args->temporalModel,
                        "the recurrent network of key 8 (cnn-temporal) (default dejag-temporal)");
    command->add_option("--jitter-spread", args->spread, "the TAAs' camera jitter in pixels")
        ->check(CLI::Range(0.0f, 64.0f))
        ->capture_default_str();
    addRuntimeOptions(command, args->runtime);
    command->footer(
        "Keys: 1-8 the method, shift+1-8 the compared one, c split or flip, f flip, space pause, n one\n"
        "frame, r reset the history, z a 4x lens on the middle, t (paused) the truth beside it, g GPU or\n"
        "CPU, o the overlay, tab the next scene, q or escape quit. The overlay (and the title) shows the\n"
        "scene, the frame, each method's time and where it ran, and the frame rate. Needs a display (a\n"
        "desktop, or xvfb-run). docs/view.md.");
    command->callback([args] {
        applyRuntimeOptions(args->runtime);
        Viewer viewer(*args);
        viewer.run();
    });
}

}  // namespace dejag::cli
