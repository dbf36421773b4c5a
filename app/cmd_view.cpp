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

#include "app/cli.h"
#include "app/commands.h"
#include "base/error.h"
#include "base/timer.h"
#include "data/frame_image.h"
#include "data/image.h"
#include "infer/filter.h"
#include "render/halton.h"
#include "render/renderer.h"
#include "render/scene.h"
#include "render/window.h"

namespace dejag::cli {
namespace {

// The methods the number keys select, in order (1 .. 8).
const char* const kMethods[] = {"none", "fxaa", "smaa", "taa", "taa-sobel", "taa-hq", "cnn", "cnn-temporal"};

struct ViewArguments {
    std::string scene = "pipe", method = "fxaa", compare, size = "960x540", script, screenshot,
                mode = "split";
    int frames = 0;  // 0: until the window closes
    float spread = 1.7f;
    RuntimeOptions runtime;
};

// A scripted key press: at frame `frame`, the key named (1-8, shift+1-8, space, n, r, c, f, z, tab, q).
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
        {"space", GLFW_KEY_SPACE}, {"n", GLFW_KEY_N}, {"r", GLFW_KEY_R},
        {"c", GLFW_KEY_C},         {"f", GLFW_KEY_F}, {"z", GLFW_KEY_Z},
        {"tab", GLFW_KEY_TAB},     {"q", GLFW_KEY_Q}, {"escape", GLFW_KEY_ESCAPE}};
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
            throw Error("script '" + path + "', line " + std::to_string(number) +
                        ": expected FRAME KEY (a key: 1-8, shift+1-8, space, n, r, c, f, z, tab, q)");
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
vec3 at(vec2 p) { return p.x < split ? texture(imageA, p).rgb : texture(imageB, p).rgb; }
void main() {
    vec2 p = uv;
    if (lens.z > 0.0 && uv.x > 0.7 && uv.y < 0.3) {
        p = lens.xy + (uv - vec2(0.85, 0.15)) / 4.0;
        colour = vec4(at(p), 1.0);
        if (abs(uv.x - 0.7) < 0.003 || abs(uv.y - 0.3) < 0.004) colour = vec4(1.0, 0.2, 0.2, 1.0);
        return;
    }
    colour = vec4(at(p), 1.0);
    if (split > 0.0 && split < 1.0 && abs(uv.x - split) < 0.0015) colour = vec4(1.0, 1.0, 1.0, 1.0);
})";

class Viewer {
  public:
    explicit Viewer(const ViewArguments& args) : args_(args) {
        const Size size = parseSize(args.size, "--size");
        width_ = size.width, height_ = size.height;
        methodA_ = methodIndex(args.method, "--method");
        methodB_ = args.compare.empty() ? -1 : methodIndex(args.compare, "--compare");
        if (args.mode != "split" && args.mode != "flip")
            throw Error("--mode is split or flip, not '" + args.mode + "'");
        flip_ = args.mode == "flip";
        for (const render::SceneInfo& info : render::sceneCatalogue()) scenes_.push_back(info.name);
        sceneIndex_ = int(std::find(scenes_.begin(), scenes_.end(), args.scene) - scenes_.begin());
        if (sceneIndex_ >= int(scenes_.size())) render::buildScene(args.scene);  // unknown: its one line
        if (!args.script.empty()) script_ = readScript(args.script);
        window_ = render::Window::open(width_, height_, "dejag view");
        window_->onKey([this](int key, int mods) { press(key, mods); });
        buildScene();
        setUpDisplay();
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
    }

  private:
    static int methodIndex(const std::string& name, const std::string& flag) {
        for (int i = 0; i < int(std::size(kMethods)); ++i)
            if (name == kMethods[i]) return i;
        std::string known;
        for (const char* m : kMethods) known += (known.empty() ? "" : ", ") + std::string(m);
        throw Error(flag + " '" + name + "' is not a method the viewer runs (" + known + ")");
    }

    void buildScene() {
        scene_ = std::make_unique<render::Scene>(render::buildScene(scenes_[size_t(sceneIndex_)]));
        renderer_ = std::make_unique<render::Renderer>(*window_, *scene_, width_, height_);
        time_ = 0;
        resetFilters();
    }

    void resetFilters() {
        infer::FilterParameters parameters;
        parameters.setPathResolver(shippedModelPath);  // the shipped networks, from any folder
        filters_[0] = infer::makeFilter(kMethods[methodA_], parameters);
        filters_[1] = methodB_ >= 0 ? infer::makeFilter(kMethods[methodB_], parameters) : nullptr;
        for (auto& f : filters_)
            if (f) f->reset();
    }

    void press(int key, int mods) {
        if (key >= GLFW_KEY_1 && key <= GLFW_KEY_8) {
            const int index = key - GLFW_KEY_1;
            if (mods & GLFW_MOD_SHIFT)
                methodB_ = index;
            else
                methodA_ = index;
            resetFilters();
            // The frame on screen is filtered again by the new method.
            if (haveFrame_) filterFrame();
        } else if (key == GLFW_KEY_SPACE) {
            paused_ = !paused_;
        } else if (key == GLFW_KEY_N) {
            step_ = true;
        } else if (key == GLFW_KEY_R) {
            for (auto& f : filters_)
                if (f) f->reset();
        } else if (key == GLFW_KEY_C) {
            flip_ = !flip_;
        } else if (key == GLFW_KEY_F) {
            showB_ = !showB_;
        } else if (key == GLFW_KEY_Z) {
            lens_ = !lens_;
        } else if (key == GLFW_KEY_TAB) {
            sceneIndex_ = (sceneIndex_ + 1) % int(scenes_.size());
            buildScene();
        } else if (key == GLFW_KEY_Q || key == GLFW_KEY_ESCAPE) {
            window_->close();
        }
    }

    // The next frame of the camera path, jittered for the TAAs, with every buffer the methods read.
    void advance() {
        render::FrameRequest request;
        request.time = double(time_);
        request.previousTime = double(time_ - 1);
        request.jitter = render::jitterPixels(unsigned(time_ % 16), args_.spread);
        request.previousJitter = render::jitterPixels(unsigned((time_ + 15) % 16), args_.spread);
        request.buffers = render::BufferSet::all();
        Stopwatch clock;
        Image image = imageFromFrame(renderer_->render(request));
        renderMs_ = clock.elapsedMs();
        infer::FrameOptions options;
        options.wanted = infer::Buffer::Albedo | infer::Buffer::Depth | infer::Buffer::Motion |
                         infer::Buffer::Ids | infer::Buffer::PreviousDepth;
        options.depthFar = scene_->far;
        options.keepExtraChannels = false;  // the colour alone (R, G, B, and A if the frame has one)
        data_ = infer::frameFromImage(image, options, "frame " + std::to_string(time_));
        data_.hasJitter = true, data_.jitter[0] = float(request.jitter.x),
        data_.jitter[1] = float(-request.jitter.y);
        haveFrame_ = true;
        filterFrame();
        ++time_;
    }

    void filterFrame() {
        for (int k = 0; k < 2; ++k) {
            if (!filters_[k]) continue;
            outputs_[k].resize(data_.colour.size());
            filters_[k]->apply(data_.frame(), outputs_[k].data());
            filterMs_[k] = filters_[k]->figures().ms;
        }
    }

    void setUpDisplay() {
        const render::GlFunctions& gl = window_->gl();
        program_ = render::compileProgram(
            gl, {{GL_VERTEX_SHADER, kVertexShader}, {GL_FRAGMENT_SHADER, kFragmentShader}},
            "the viewer's display program");
        gl.GenVertexArrays(1, &vertexArray_);
        gl.GenTextures(2, textures_);
        for (GLuint t : textures_) {
            gl.BindTexture(GL_TEXTURE_2D, t);
            gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
            gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
            gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
            gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
        }
    }

    void upload(GLuint texture, const std::vector<float>& rgb) {
        const render::GlFunctions& gl = window_->gl();
        gl.BindTexture(GL_TEXTURE_2D, texture);
        gl.PixelStorei(GL_UNPACK_ALIGNMENT, 4);
        const bool alpha = data_.colourNames.size() == 4;
        gl.TexImage2D(GL_TEXTURE_2D, 0, alpha ? GL_RGBA32F : GL_RGB32F, width_, height_, 0,
                      alpha ? GL_RGBA : GL_RGB, GL_FLOAT, rgb.data());
    }

    void draw() {
        const render::GlFunctions& gl = window_->gl();
        if (!haveFrame_) return;
        const bool compare = filters_[1] != nullptr;
        upload(textures_[0], outputs_[0]);
        if (compare) upload(textures_[1], outputs_[1]);
        int fw = 0, fh = 0;
        window_->framebufferSize(&fw, &fh);
        gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
        gl.Viewport(0, 0, fw, fh);
        gl.Disable(GL_DEPTH_TEST);
        gl.UseProgram(program_);
        gl.ActiveTexture(GL_TEXTURE0);
        gl.BindTexture(GL_TEXTURE_2D, textures_[0]);
        gl.ActiveTexture(GL_TEXTURE1);
        gl.BindTexture(GL_TEXTURE_2D, textures_[compare ? 1 : 0]);
        gl.Uniform1i(gl.GetUniformLocation(program_, "imageA"), 0);
        gl.Uniform1i(gl.GetUniformLocation(program_, "imageB"), 1);
        // Split: A left of the middle, B right; flip: one of them whole (f switches).
        const float split = !compare ? 1.0f : flip_ ? (showB_ ? 0.0f : 1.0f) : 0.5f;
        gl.Uniform1f(gl.GetUniformLocation(program_, "split"), split);
        gl.Uniform3f(gl.GetUniformLocation(program_, "lens"), 0.5f, 0.5f, lens_ ? 1.0f : 0.0f);
        gl.BindVertexArray(vertexArray_);
        gl.DrawArrays(GL_TRIANGLES, 0, 3);
        // The overlay: what is shown and each pass's time, in the title (the CPU passes; GPU timer queries
        // where the methods run on the GPU).
        const double now = fps_.elapsedMs();
        frameMs_ = 0.9 * frameMs_ + 0.1 * (now - lastFrame_);
        lastFrame_ = now;
        char title[512];
        std::snprintf(
            title, sizeof title, "dejag view  %s  frame %d%s  A: %s %.1f ms%s%s  render %.1f ms  %.0f fps",
            scenes_[size_t(sceneIndex_)].c_str(), time_ - 1, paused_ ? " (paused)" : "", kMethods[methodA_],
            filterMs_[0], compare ? "  B: " : "",
            compare ? (std::string(kMethods[methodB_]) + " " + std::to_string(int(filterMs_[1] + 0.5)) +
                       " ms" + (flip_ ? (showB_ ? " [shown]" : " [hidden]") : ""))
                          .c_str()
                    : "",
            renderMs_, frameMs_ > 0 ? 1000.0 / frameMs_ : 0.0);
        window_->setTitle(title);
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
    int sceneIndex_ = 0, methodA_ = 0, methodB_ = -1;
    std::vector<ScriptedKey> script_;
    std::unique_ptr<render::Window> window_;
    std::unique_ptr<render::Scene> scene_;
    std::unique_ptr<render::Renderer> renderer_;
    std::unique_ptr<infer::Filter> filters_[2];
    infer::FrameData data_;
    std::vector<float> outputs_[2];
    bool haveFrame_ = false, paused_ = false, step_ = false, flip_ = false, showB_ = false, lens_ = false;
    int time_ = 0, shown_ = 0;
    double renderMs_ = 0, filterMs_[2] = {0, 0}, frameMs_ = 0, lastFrame_ = 0;
    Stopwatch fps_;
    GLuint program_ = 0, vertexArray_ = 0, textures_[2] = {0, 0};
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
    command->add_option("--jitter-spread", args->spread, "the TAAs' camera jitter in pixels")
        ->check(CLI::Range(0.0f, 64.0f))
        ->capture_default_str();
    addRuntimeOptions(command, args->runtime);
    command->footer(
        "Keys: 1-8 the method, shift+1-8 the compared one, c split or flip, f flip, space pause, n one "
        "frame,\n"
        "r reset the history, z a 4x lens on the middle, tab the next scene, q or escape quit. The window's\n"
        "title shows the scene, the frame, each method's time and the frame rate. Needs a display (a "
        "desktop,\n"
        "or xvfb-run). docs/view.md.");
    command->callback([args] {
        applyRuntimeOptions(args->runtime);
        Viewer viewer(*args);
        viewer.run();
    });
}

}  // namespace dejag::cli
