#include "render/gl.h"

#include <chrono>

#include <GL/osmesa.h>

#include <string>
#include <vector>

#include "base/error.h"

namespace dejag::render {

void GlContext::loadFunctions() {
#define DEJAG_GL_LOAD(type, name)                                            \
    gl_.name = reinterpret_cast<PFNGL##type##PROC>(procAddress("gl" #name)); \
    if (!gl_.name) throw Error("OpenGL: the context has no gl" #name " (OpenGL 3.3+ core needed)");
    DEJAG_GL_FUNCTIONS(DEJAG_GL_LOAD)
#undef DEJAG_GL_LOAD
}

const GlFunctions& GlContext::compute() {
    if (computeLoaded_) return gl_;
#define DEJAG_GL_LOAD_COMPUTE(type, name)                                                                 \
    gl_.name = reinterpret_cast<PFNGL##type##PROC>(procAddress("gl" #name));                              \
    if (!gl_.name)                                                                                        \
        throw Error("OpenGL: the context has no gl" #name " (compute shaders need OpenGL 4.3; this is " + \
                    description() + ")");
    DEJAG_GL_COMPUTE_FUNCTIONS(DEJAG_GL_LOAD_COMPUTE)
#undef DEJAG_GL_LOAD_COMPUTE
    computeLoaded_ = true;
    return gl_;
}

GLuint compileProgram(const GlFunctions& gl, std::initializer_list<std::pair<GLenum, const char*>> stages,
                      const std::string& what) {
    std::vector<GLuint> shaders;
    const auto release = [&] {
        for (GLuint shader : shaders) gl.DeleteShader(shader);
    };
    for (const auto& [type, source] : stages) {
        const GLuint shader = gl.CreateShader(type);
        shaders.push_back(shader);
        gl.ShaderSource(shader, 1, &source, nullptr);
        gl.CompileShader(shader);
        GLint ok = 0;
        gl.GetShaderiv(shader, GL_COMPILE_STATUS, &ok);
        if (!ok) {
            char log[4096] = {};
            gl.GetShaderInfoLog(shader, sizeof log, nullptr, log);
            release();
            throw Error(what + " does not compile: " + log);
        }
    }
    const GLuint program = gl.CreateProgram();
    for (GLuint shader : shaders) gl.AttachShader(program, shader);
    gl.LinkProgram(program);
    release();
    GLint ok = 0;
    gl.GetProgramiv(program, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[4096] = {};
        gl.GetProgramInfoLog(program, sizeof log, nullptr, log);
        gl.DeleteProgram(program);
        throw Error(what + " does not link: " + log);
    }
    return program;
}

GLuint compileComputeProgram(const GlFunctions& gl, const std::string& source, const std::string& what) {
    return compileProgram(gl, {{GL_COMPUTE_SHADER, source.c_str()}}, what);
}

namespace {

class OsMesaContext final : public GlContext {
  public:
    OsMesaContext() {
        // OpenGL 4.5 core first (llvmpipe's level), then 3.3 core, the least the shaders need.
        for (const int major : {4, 3}) {
            const int minor = major == 4 ? 5 : 3;
            const int attributes[] = {OSMESA_FORMAT,
                                      OSMESA_RGBA,
                                      OSMESA_DEPTH_BITS,
                                      24,
                                      OSMESA_STENCIL_BITS,
                                      8,
                                      OSMESA_PROFILE,
                                      OSMESA_CORE_PROFILE,
                                      OSMESA_CONTEXT_MAJOR_VERSION,
                                      major,
                                      OSMESA_CONTEXT_MINOR_VERSION,
                                      minor,
                                      0};
            context_ = OSMesaCreateContextAttribs(attributes, nullptr);
            if (context_) break;
        }
        if (!context_)
            throw Error(
                "OSMesa unavailable: cannot create an OpenGL 3.3+ core context (is libosmesa6 installed?)");
        // The default framebuffer is never drawn to (every pass renders into textures), so 1x1 suffices.
        if (!OSMesaMakeCurrent(context_, buffer_, GL_UNSIGNED_BYTE, 1, 1)) {
            OSMesaDestroyContext(context_);
            throw Error("OSMesa unavailable: cannot make the context current");
        }
        loadFunctions();
        const auto text = [&](GLenum name) {
            const GLubyte* s = gl_.GetString(name);
            return s ? std::string(reinterpret_cast<const char*>(s)) : std::string("?");
        };
        description_ = "OSMesa: " + text(GL_RENDERER) + ", OpenGL " + text(GL_VERSION);
    }
    ~OsMesaContext() override { OSMesaDestroyContext(context_); }
    OsMesaContext(const OsMesaContext&) = delete;
    OsMesaContext& operator=(const OsMesaContext&) = delete;

    GlProc procAddress(const char* name) const override { return OSMesaGetProcAddress(name); }
    std::string description() const override { return description_; }

  private:
    OSMesaContext context_ = nullptr;
    unsigned char buffer_[16] = {};
    std::string description_;
};

}  // namespace

std::unique_ptr<GlContext> createOsMesaContext() {
    return std::make_unique<OsMesaContext>();
}

void timedPass(GlContext& context, const std::string& name, const std::function<void()>& work) {
    PassTimer* timer = context.passTimer;
    if (!timer) return work();
    const GlFunctions& gl = context.gl();
    if (timer->wallClock) {
        gl.Finish();
        const auto start = std::chrono::steady_clock::now();
        work();
        gl.Finish();
        timer->passes.push_back(
            {name,
             std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count()});
        return;
    }
    GLuint query = 0;
    gl.GenQueries(1, &query);
    gl.BeginQuery(GL_TIME_ELAPSED, query);
    work();
    gl.EndQuery(GL_TIME_ELAPSED);
    GLuint64 nanoseconds = 0;
    gl.GetQueryObjectui64v(query, GL_QUERY_RESULT, &nanoseconds);
    gl.DeleteQueries(1, &query);
    timer->passes.push_back({name, double(nanoseconds) * 1e-6});
}

void dispatchPass(GlContext& context, const std::string& name, int width, int height) {
    const GlFunctions& gl = context.compute();
    timedPass(context, name, [&] {
        gl.DispatchCompute(GLuint((width + 7) / 8), GLuint((height + 7) / 8), 1);
        gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    });
}

}  // namespace dejag::render
