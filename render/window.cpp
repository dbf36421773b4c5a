// A GLFW window as a GlContext: see render/window.h.
#include "render/window.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <cstdlib>

#include "base/error.h"

namespace dejag::render {
namespace {

std::string lastGlfwError() {
    const char* text = nullptr;
    glfwGetError(&text);
    return text ? text : "unknown reason";
}

}  // namespace

std::unique_ptr<Window> Window::open(int width, int height, const std::string& title) {
    const char* display = std::getenv("DISPLAY");
    const char* wayland = std::getenv("WAYLAND_DISPLAY");
    if ((!display || !*display) && (!wayland || !*wayland))
        throw Error(
            "cannot open a window: no display (DISPLAY is not set; run on a desktop, or under "
            "xvfb-run for a virtual one)");
    if (!glfwInit()) throw Error("cannot open a window: " + lastGlfwError());
    std::unique_ptr<Window> window(new Window());
    for (const int major : {4, 3}) {
        glfwDefaultWindowHints();
        glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, major);
        glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, major == 4 ? 5 : 3);
        glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
        glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
        glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);
        window->window_ = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
        if (window->window_) break;
    }
    if (!window->window_) {
        const std::string reason = lastGlfwError();
        glfwTerminate();
        throw Error("cannot open a window with an OpenGL 3.3+ core context: " + reason);
    }
    GLFWwindow* w = static_cast<GLFWwindow*>(window->window_);
    glfwMakeContextCurrent(w);
    glfwSwapInterval(0);
    glfwSetWindowUserPointer(w, window.get());
    glfwSetKeyCallback(w, [](GLFWwindow* handle, int key, int, int action, int mods) {
        auto* self = static_cast<Window*>(glfwGetWindowUserPointer(handle));
        if (action == GLFW_PRESS && self->keyHandler_) self->keyHandler_(key, mods);
    });
    window->loadFunctions();
    const GLubyte* renderer = window->gl().GetString(GL_RENDERER);
    const GLubyte* version = window->gl().GetString(GL_VERSION);
    window->description_ = std::string("GLFW window: ") + (renderer ? (const char*)renderer : "?") +
                           ", OpenGL " + (version ? (const char*)version : "?");
    return window;
}

Window::~Window() {
    if (window_) glfwDestroyWindow(static_cast<GLFWwindow*>(window_));
    glfwTerminate();
}

bool Window::shouldClose() const {
    return glfwWindowShouldClose(static_cast<GLFWwindow*>(window_));
}
void Window::close() {
    glfwSetWindowShouldClose(static_cast<GLFWwindow*>(window_), GLFW_TRUE);
}
void Window::setTitle(const std::string& title) {
    glfwSetWindowTitle(static_cast<GLFWwindow*>(window_), title.c_str());
}
void Window::framebufferSize(int* width, int* height) const {
    glfwGetFramebufferSize(static_cast<GLFWwindow*>(window_), width, height);
}
void Window::swapBuffers() {
    glfwSwapBuffers(static_cast<GLFWwindow*>(window_));
}
void Window::pollEvents() {
    glfwPollEvents();
}
GlProc Window::procAddress(const char* name) const {
    return reinterpret_cast<GlProc>(glfwGetProcAddress(name));
}

}  // namespace dejag::render
