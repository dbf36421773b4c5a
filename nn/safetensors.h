// dejag/nn: the safetensors file layout (8-byte little-endian header length, a JSON header naming each
// tensor's dtype, shape and byte range, then raw little-endian data), with free-form string metadata.
//
// Reading validates everything before trusting it: header length against the file size, every shape,
// dtype and byte range, and that ranges neither overlap nor run past the data; a bad file is a
// dejag::Error naming the file and the problem, never an out-of-bounds read.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "nn/tensor.h"

namespace dejag::nn {

struct StoredTensor {
    std::string dtype;  // "F32" or "F64"
    Shape shape;
    std::vector<float> f32;   // F32 data
    std::vector<double> f64;  // F64 data
    int64_t numel() const { return shapeNumel(shape); }
    // F32 data, or F64 data converted to float.
    std::vector<float> asFloat() const;
    std::vector<double> asDouble() const;
};

struct SafetensorsFile {
    std::map<std::string, StoredTensor> tensors;
    std::map<std::string, std::string> metadata;
    const StoredTensor& at(const std::string& name) const;  // throws dejag::Error if absent
};

SafetensorsFile readSafetensors(const std::string& path);
SafetensorsFile parseSafetensors(const std::string& bytes, const std::string& nameForErrors);

struct TensorToWrite {
    std::string name;
    Shape shape;
    const float* data = nullptr;
};
// Written atomically (temporary file, then rename).
void writeSafetensors(const std::string& path, const std::vector<TensorToWrite>& tensors,
                      const std::map<std::string, std::string>& metadata);

}  // namespace dejag::nn
