// dejag/nn: a model as GLSL compute shaders (OpenGL 4.3+, GLSL 430), for an engine's post-process chain.
//
// One compute pass per node of the graph (a concatenation is one copy pass per input), each a
// self-contained shader whose shapes, offsets and activation are compiled in as constants; the weights go
// in one shader storage buffer (binding 0), in the model's own order. Every tensor is a storage buffer of
// planar float32 (channel, row, column); a pass reads its inputs at bindings 1-3 and writes binding 4,
// with the uniforms `inSize` (width, height of its first input) and `outSize` (of its output), dispatched
// as ceil(outSize / 8) work groups of 8 x 8. A recurrent network's ops (warp, accumulate) have their
// passes too: the network computes one frame from the input its caller assembles (infer/glsl_filter.h).
//
// docs/glsl.md has the layout a runtime binds; infer/glsl_network.h runs it (OSMesa in the tests).
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "nn/model.h"

namespace dejag::nn {

// A tensor of the network: its channels and its size relative to the input's (num / den of each side).
struct GlslBuffer {
    std::string name;
    int channels = 0;
    int scaleNum = 1, scaleDen = 1;
};

struct GlslPass {
    std::string name;                 // the shader's file stem ("03_enc2")
    std::string source;               // GLSL 430
    std::vector<std::string> inputs;  // buffer names bound at 1, 2, 3
    std::string output;               // buffer name bound at 4
};

struct GlslNetwork {
    std::string model;  // the model's name
    nlohmann::json architecture;
    int inputChannels = 0, outputChannels = 0;
    int sizeDivisor = 1;              // the input's width and height must be multiples of it
    std::vector<GlslBuffer> buffers;  // buffers[0] is "input"
    std::vector<GlslPass> passes;     // in order
    std::string output;               // the buffer holding the result
    std::vector<float> weights;       // binding 0

    // network.json: everything but the shader sources and the weights (which are files of their own).
    nlohmann::json description() const;
};

// A float as a GLSL literal that reads back to the same float ("0.166000003", "2.0").
std::string glslFloat(float v);

// Throws dejag::Error naming a node whose op has no GLSL form.
GlslNetwork exportGlsl(const Model& model);

// Written as a folder: network.json, weights.bin (little-endian float32), one NN_NAME.comp per pass.
// Files are written atomically; the folder is created if missing.
void writeGlslNetwork(const std::string& folder, const GlslNetwork& network);
// Reads such a folder back (throws dejag::Error naming a missing or inconsistent file).
GlslNetwork readGlslNetwork(const std::string& folder);

}  // namespace dejag::nn
