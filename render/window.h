// dejag/render: an on-screen OpenGL context, a GLFW window (OpenGL 4.5 core, else 3.3), behind the same
// GlContext the renderer draws with off screen; what `dejag view` shows its frames in.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "render/gl.h"

namespace dejag::render {

class Window : public GlContext {
  public:
    // Throws dejag::Error in one line when no window can open (no display: run under xvfb-run or on a
    // desktop; or no OpenGL 3.3 core context).
    static std::unique_ptr<Window> open(int width, int height, const std::string& title);
    ~Window() override;

    bool shouldClose() const;
    void close();
    void setTitle(const std::string& title);
    // The window's framebuffer size in pixels.
    void framebufferSize(int* width, int* height) const;
    void swapBuffers();
    // Handles pending events; key presses go to the handler (GLFW key codes and modifier bits).
    void pollEvents();
    void onKey(std::function<void(int key, int mods)> handler) { keyHandler_ = std::move(handler); }

    GlProc procAddress(const char* name) const override;
    std::string description() const override { return description_; }

  private:
    Window() = default;
    void* window_ = nullptr;  // GLFWwindow*
    std::string description_;
    std::function<void(int, int)> keyHandler_;
};

}  // namespace dejag::render
