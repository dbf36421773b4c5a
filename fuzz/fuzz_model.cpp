// Fuzz target: the model loader — a safetensors file (header JSON, tensor table, data) holding the
// architecture JSON in its metadata — then, for a model that loads, one forward pass on a small input.
#include <cstdint>
#include <map>

#include "base/error.h"
#include "fuzz/fuzz_util.h"
#include "nn/model.h"
#include "nn/tensor.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = dejag::fuzz::writeScratchFile("model.safetensors", data, size);
    try {
        std::map<std::string, std::string> metadata;
        dejag::nn::Model model = dejag::nn::loadModel(path, &metadata);
        if (model.parameterCount() > (1 << 20)) return 0;  // loads fine; too large to run per input
        const int channels = model.inputChannels();
        dejag::nn::Tensor input({1, channels, 16, 16});
        for (int64_t i = 0; i < input.numel(); ++i) input.data()[i] = float(i % 7) / 7.0f;
        (void)model.forward(input);
    } catch (const dejag::Error&) {
    }
    return 0;
}
