// Runs nn/glsl.h's passes: see infer/glsl_network.h.
#include "infer/glsl_network.h"

#include <map>

#include "base/error.h"
#include "base/timer.h"

namespace dejag::infer {

GlslNetworkRunner::GlslNetworkRunner(render::GlContext& context, nn::GlslNetwork network)
    : context_(context), network_(std::move(network)) {
    const render::GlFunctions& gl = context_.compute();
    for (const nn::GlslPass& pass : network_.passes)
        programs_.push_back(render::compileComputeProgram(gl, pass.source, "GLSL pass '" + pass.name + "'"));
    gl.GenBuffers(1, &weights_);
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, weights_);
    gl.BufferData(GL_SHADER_STORAGE_BUFFER,
                  GLsizeiptr(std::max<size_t>(network_.weights.size(), 1) * sizeof(float)),
                  network_.weights.empty() ? nullptr : network_.weights.data(), GL_STATIC_DRAW);
}

GlslNetworkRunner::~GlslNetworkRunner() {
    const render::GlFunctions& gl = context_.gl();
    for (unsigned program : programs_) gl.DeleteProgram(program);
    if (!buffers_.empty()) gl.DeleteBuffers(GLsizei(buffers_.size()), buffers_.data());
    if (weights_) gl.DeleteBuffers(1, &weights_);
}

std::pair<int, int> GlslNetworkRunner::sizeOf(size_t buffer) const {
    const nn::GlslBuffer& b = network_.buffers[buffer];
    return {width_ * b.scaleNum / b.scaleDen, height_ * b.scaleNum / b.scaleDen};
}

unsigned GlslNetworkRunner::prepare(int width, int height) {
    const int d = network_.sizeDivisor;
    if (width <= 0 || height <= 0 || width % d != 0 || height % d != 0)
        throw Error("GLSL network '" + network_.model + "': " + std::to_string(width) + "x" +
                    std::to_string(height) + " is not a multiple of " + std::to_string(d) + " on each side");
    const render::GlFunctions& gl = context_.compute();
    if (width != width_ || height != height_) {
        if (!buffers_.empty()) gl.DeleteBuffers(GLsizei(buffers_.size()), buffers_.data());
        buffers_.assign(network_.buffers.size(), 0);
        gl.GenBuffers(GLsizei(buffers_.size()), buffers_.data());
        width_ = width, height_ = height;
        for (size_t i = 0; i < buffers_.size(); ++i) {
            const auto [w, h] = sizeOf(i);
            gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, buffers_[i]);
            gl.BufferData(
                GL_SHADER_STORAGE_BUFFER,
                GLsizeiptr(size_t(network_.buffers[i].channels) * size_t(w) * size_t(h) * sizeof(float)),
                nullptr, GL_DYNAMIC_COPY);
        }
    }
    return buffers_[0];
}

unsigned GlslNetworkRunner::dispatch() {
    const render::GlFunctions& gl = context_.compute();
    std::map<std::string, size_t> index;
    for (size_t i = 0; i < network_.buffers.size(); ++i) index[network_.buffers[i].name] = i;
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, weights_);
    for (size_t p = 0; p < network_.passes.size(); ++p) {
        const nn::GlslPass& pass = network_.passes[p];
        gl.UseProgram(programs_[p]);
        for (size_t k = 0; k < pass.inputs.size(); ++k)
            gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, GLuint(1 + k), buffers_[index.at(pass.inputs[k])]);
        const size_t out = index.at(pass.output);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, buffers_[out]);
        const auto [inW, inH] = sizeOf(index.at(pass.inputs[0]));
        const auto [outW, outH] = sizeOf(out);
        gl.Uniform2i(gl.GetUniformLocation(programs_[p], "inSize"), inW, inH);
        gl.Uniform2i(gl.GetUniformLocation(programs_[p], "outSize"), outW, outH);
        render::dispatchPass(context_, pass.name, outW, outH);
    }
    return buffers_[index.at(network_.output)];
}

std::vector<float> GlslNetworkRunner::run(const float* input, int width, int height) {
    Stopwatch timer;
    const render::GlFunctions& gl = context_.compute();
    const unsigned in = prepare(width, height);
    const size_t inputCount = size_t(network_.inputChannels) * size_t(width) * size_t(height);
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, in);
    gl.BufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(inputCount * sizeof(float)), input);
    const unsigned out = dispatch();
    gl.MemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    size_t outIndex = 0;
    while (network_.buffers[outIndex].name != network_.output) ++outIndex;
    const auto [outW, outH] = sizeOf(outIndex);
    std::vector<float> result(size_t(network_.buffers[outIndex].channels) * size_t(outW) * size_t(outH));
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, out);
    gl.GetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(result.size() * sizeof(float)),
                        result.data());
    if (const GLenum error = gl.GetError(); error != GL_NO_ERROR)
        throw Error("GLSL network '" + network_.model + "': OpenGL error " + std::to_string(error));
    lastMs_ = timer.elapsedMs();
    return result;
}

}  // namespace dejag::infer
