// Fuzz target: the image loading path — a PNG, EXR, TIFF or JPEG file (the first byte picks which) read
// through OpenImageIO into an Image, its named-channel lookup (R G B, depth.Z, id.ID as dejag render
// writes them), the sRGB conversions and the region masks computed from the buffers.
#include <cstdint>

#include "base/error.h"
#include "data/evaluation.h"
#include "data/image.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size < 1) return 0;
    static const char* const kExtensions[] = {"png", "exr", "tif", "jpg"};
    const std::string path =
        dejag::fuzz::writeScratchFile(std::string("image.") + kExtensions[data[0] % 4], data + 1, size - 1);
    try {
        // Headers claiming more than 4M samples are refused before reading (the row-wise allocation behind
        // larger ones has its own test; under ASan each large allocation costs a second of shadow memory).
        dejag::Image image = dejag::readImage(path, int64_t(1) << 22);
        (void)dejag::findNonFinite(image);
        const int r = image.findChannel("R");
        if (r >= 0 && image.findChannel("G") == r + 1 && image.findChannel("B") == r + 2 &&
            image.findChannel("id.ID") >= 0 && image.findChannel("depth.Z") >= 0) {
            dejag::data::EvaluationItem item;
            item.id = "fuzz";
            item.truth = image;
            dejag::data::computeRegionMasks(item, image);
        }
        dejag::convertSrgbToLinear(image);
        dejag::convertLinearToSrgb(image);
    } catch (const dejag::Error&) {
    }
    return 0;
}
