// dejag/render: the OpenGL context behind one small interface, and the GL functions dejag calls,
// loaded through that context (so the same renderer can draw with OSMesa or, later, into a GLFW window
// without two libraries' GL symbols colliding).
#pragma once

#include <GL/glcorearb.h>

#include <functional>
#include <initializer_list>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace dejag::render {

// GL 1.0-4.5 core functions used by the renderer: X(TYPE, Name) for glName with PFNGLTYPEPROC.
#define DEJAG_GL_FUNCTIONS(X)                                         \
    X(GETSTRING, GetString)                                           \
    X(GETINTEGERV, GetIntegerv)                                       \
    X(GETERROR, GetError)                                             \
    X(VIEWPORT, Viewport)                                             \
    X(CLEARCOLOR, ClearColor)                                         \
    X(CLEAR, Clear)                                                   \
    X(CLEARBUFFERFV, ClearBufferfv)                                   \
    X(CLEARBUFFERFI, ClearBufferfi)                                   \
    X(ENABLE, Enable)                                                 \
    X(DISABLE, Disable)                                               \
    X(DEPTHFUNC, DepthFunc)                                           \
    X(DEPTHMASK, DepthMask)                                           \
    X(COLORMASK, ColorMask)                                           \
    X(BLENDFUNC, BlendFunc)                                           \
    X(SCISSOR, Scissor)                                               \
    X(STENCILFUNC, StencilFunc)                                       \
    X(STENCILOP, StencilOp)                                           \
    X(STENCILMASK, StencilMask)                                       \
    X(FINISH, Finish)                                                 \
    X(GENFRAMEBUFFERS, GenFramebuffers)                               \
    X(DELETEFRAMEBUFFERS, DeleteFramebuffers)                         \
    X(BINDFRAMEBUFFER, BindFramebuffer)                               \
    X(FRAMEBUFFERTEXTURE2D, FramebufferTexture2D)                     \
    X(FRAMEBUFFERRENDERBUFFER, FramebufferRenderbuffer)               \
    X(CHECKFRAMEBUFFERSTATUS, CheckFramebufferStatus)                 \
    X(DRAWBUFFERS, DrawBuffers)                                       \
    X(READBUFFER, ReadBuffer)                                         \
    X(READPIXELS, ReadPixels)                                         \
    X(BLITFRAMEBUFFER, BlitFramebuffer)                               \
    X(GENRENDERBUFFERS, GenRenderbuffers)                             \
    X(DELETERENDERBUFFERS, DeleteRenderbuffers)                       \
    X(BINDRENDERBUFFER, BindRenderbuffer)                             \
    X(RENDERBUFFERSTORAGE, RenderbufferStorage)                       \
    X(RENDERBUFFERSTORAGEMULTISAMPLE, RenderbufferStorageMultisample) \
    X(GENTEXTURES, GenTextures)                                       \
    X(DELETETEXTURES, DeleteTextures)                                 \
    X(BINDTEXTURE, BindTexture)                                       \
    X(ACTIVETEXTURE, ActiveTexture)                                   \
    X(TEXIMAGE2D, TexImage2D)                                         \
    X(TEXPARAMETERI, TexParameteri)                                   \
    X(TEXPARAMETERF, TexParameterf)                                   \
    X(GENERATEMIPMAP, GenerateMipmap)                                 \
    X(PIXELSTOREI, PixelStorei)                                       \
    X(CREATESHADER, CreateShader)                                     \
    X(SHADERSOURCE, ShaderSource)                                     \
    X(COMPILESHADER, CompileShader)                                   \
    X(GETSHADERIV, GetShaderiv)                                       \
    X(GETSHADERINFOLOG, GetShaderInfoLog)                             \
    X(DELETESHADER, DeleteShader)                                     \
    X(CREATEPROGRAM, CreateProgram)                                   \
    X(ATTACHSHADER, AttachShader)                                     \
    X(LINKPROGRAM, LinkProgram)                                       \
    X(GETPROGRAMIV, GetProgramiv)                                     \
    X(GETPROGRAMINFOLOG, GetProgramInfoLog)                           \
    X(USEPROGRAM, UseProgram)                                         \
    X(DELETEPROGRAM, DeleteProgram)                                   \
    X(GETUNIFORMLOCATION, GetUniformLocation)                         \
    X(UNIFORM1I, Uniform1i)                                           \
    X(UNIFORM1UI, Uniform1ui)                                         \
    X(UNIFORM1F, Uniform1f)                                           \
    X(UNIFORM2F, Uniform2f)                                           \
    X(UNIFORM3F, Uniform3f)                                           \
    X(UNIFORM4F, Uniform4f)                                           \
    X(UNIFORMMATRIX4FV, UniformMatrix4fv)                             \
    X(GENVERTEXARRAYS, GenVertexArrays)                               \
    X(DELETEVERTEXARRAYS, DeleteVertexArrays)                         \
    X(BINDVERTEXARRAY, BindVertexArray)                               \
    X(GENBUFFERS, GenBuffers)                                         \
    X(DELETEBUFFERS, DeleteBuffers)                                   \
    X(BINDBUFFER, BindBuffer)                                         \
    X(BUFFERDATA, BufferData)                                         \
    X(VERTEXATTRIBPOINTER, VertexAttribPointer)                       \
    X(ENABLEVERTEXATTRIBARRAY, EnableVertexAttribArray)               \
    X(DRAWELEMENTS, DrawElements)                                     \
    X(DRAWARRAYS, DrawArrays)                                         \
    X(GENQUERIES, GenQueries)                                         \
    X(DELETEQUERIES, DeleteQueries)                                   \
    X(BEGINQUERY, BeginQuery)                                         \
    X(ENDQUERY, EndQuery)                                             \
    X(GETQUERYOBJECTUI64V, GetQueryObjectui64v)

// OpenGL 4.3 compute: shader storage buffers and dispatches (the networks as GLSL, infer/glsl_network.h),
// loaded on first use so that a 3.3 context still renders.
#define DEJAG_GL_COMPUTE_FUNCTIONS(X)       \
    X(DISPATCHCOMPUTE, DispatchCompute)     \
    X(MEMORYBARRIER, MemoryBarrier)         \
    X(BINDBUFFERBASE, BindBufferBase)       \
    X(GETBUFFERSUBDATA, GetBufferSubData)   \
    X(BUFFERSUBDATA, BufferSubData)         \
    X(COPYBUFFERSUBDATA, CopyBufferSubData) \
    X(UNIFORM2I, Uniform2i)

struct GlFunctions {
#define DEJAG_GL_DECLARE(type, name) PFNGL##type##PROC name = nullptr;
    DEJAG_GL_FUNCTIONS(DEJAG_GL_DECLARE)
    DEJAG_GL_COMPUTE_FUNCTIONS(DEJAG_GL_DECLARE)
#undef DEJAG_GL_DECLARE
};

using GlProc = void (*)();

// Times the compute passes dispatched through dispatchPass() while it is set on a context (dejag view):
// each by a GL_TIME_ELAPSED query, or (wallClock) between two glFinish calls, for drivers such as
// llvmpipe that do a dispatch's work after the query has ended.
struct PassTimer {
    bool wallClock = false;
    std::vector<std::pair<std::string, double>> passes;  // name, milliseconds, in dispatch order
};

// A current OpenGL (>= 3.3 core) context.
class GlContext {
  public:
    virtual ~GlContext() = default;
    virtual GlProc procAddress(const char* name) const = 0;
    // e.g. "OSMesa: llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5 core"
    virtual std::string description() const = 0;
    const GlFunctions& gl() const { return gl_; }
    // gl() with the compute functions loaded too; throws dejag::Error if the context has none (below 4.3).
    const GlFunctions& compute();
    // While set, dispatchPass() times each pass into it.
    PassTimer* passTimer = nullptr;

  protected:
    // Loads every function of DEJAG_GL_FUNCTIONS; throws dejag::Error naming the first one missing.
    void loadFunctions();
    GlFunctions gl_;
    bool computeLoaded_ = false;
};

// Shader stages ({GL_VERTEX_SHADER, source}, ...) compiled and linked into a program. Throws dejag::Error
// with the compiler's or linker's log, naming `what`.
GLuint compileProgram(const GlFunctions& gl, std::initializer_list<std::pair<GLenum, const char*>> stages,
                      const std::string& what);
// A compute shader as a program (needs compute(): OpenGL 4.3).
GLuint compileComputeProgram(const GlFunctions& gl, const std::string& source, const std::string& what);

// One compute pass over width x height pixels (work groups of 8 x 8) with the bound program, then a
// storage-buffer barrier; timed into context.passTimer when one is set.
void dispatchPass(GlContext& context, const std::string& name, int width, int height);
// Any other GPU work (a buffer copy) timed as a pass the same way.
void timedPass(GlContext& context, const std::string& name, const std::function<void()>& work);

// The default: an off-screen OSMesa context (llvmpipe). Throws dejag::Error if OSMesa cannot create an
// OpenGL 3.3+ core context.
std::unique_ptr<GlContext> createOsMesaContext();

}  // namespace dejag::render
