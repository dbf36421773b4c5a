// Writes the fuzzers' seed corpora (committed under fuzz/corpus/, regenerate with `make fuzz-seeds`):
// small valid inputs of each kind, which the fuzzers mutate into invalid ones.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "data/image.h"
#include "nn/model.h"

namespace fs = std::filesystem;
using namespace dejag;

namespace {

void writeText(const fs::path& path, const std::string& text) {
    std::ofstream(path, std::ios::binary) << text;
}

// An image file with a leading byte choosing its format, as fuzz_image.cpp reads it.
void writeImageSeed(const fs::path& folder, const std::string& name, char format, const Image& image,
                    const std::string& extension) {
    const fs::path file = folder / ("tmp." + extension);
    writeImage(file.string(), image);
    std::ifstream in(file, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    writeText(folder / name, std::string(1, format) + bytes);
    fs::remove(file);
}

Image gradient(int width, int height, const std::vector<std::string>& channels, PixelType type) {
    Image image(width, height, channels, type);
    for (size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] = float(i % 17) / 16.0f;
    return image;
}

}  // namespace

int main(int argc, char** argv) {
    const fs::path root = argc > 1 ? argv[1] : "fuzz/corpus";
    for (const char* target : {"fuzz_model", "fuzz_manifest", "fuzz_image", "fuzz_cli_numbers"})
        fs::create_directories(root / target);

    // Models: the smallest network of the fast family (RGB), and of it with one input channel (the seed
    // network itself is 640 KB, too large a seed to mutate).
    for (const int channels : {3, 1}) {
        nn::Model fast = nn::Model::builtin("fast", {4, 2, channels});
        fast.initialize(uint64_t(channels));
        nn::saveModel((root / "fuzz_model" / ("fast-" + std::to_string(channels) + ".safetensors")).string(),
                      fast);
    }
    // Manifests: records as dejag data generate writes them.
    auto record = [](int index, const std::string& family, const std::string& split) {
        const std::string id = family + "-" + std::to_string(index);
        return std::string(R"({"index":)") + std::to_string(index) + R"(,"id":")" + id + R"(","family":")" +
               family + R"(","split":")" + split +
               R"(","size":[64,48],"edge_fraction":0.12,"aliased_psnr":31.5,)" +
               R"("files":{"input":{"path":"items/)" + id +
               R"(_input.exr","bytes":1234,"checksum":"9f2c"},)" + R"("truth":{"path":"items/)" + id +
               R"(_truth.exr","bytes":1300,"checksum":"77aa"}}})" + "\n";
    };
    writeText(root / "fuzz_manifest" / "two-records.jsonl",
              record(0, "shapes", "train") + record(1, "text", "test"));
    writeText(root / "fuzz_manifest" / "empty.jsonl", "");
    // Images: an 8-bit PNG, a float EXR with dejag render's buffers, a 16-bit TIFF, a JPEG.
    const fs::path images = root / "fuzz_image";
    writeImageSeed(images, "rgb.png.bin", 0, gradient(8, 6, {"R", "G", "B"}, PixelType::UInt8), "png");
    writeImageSeed(images, "buffers.exr.bin", 1,
                   gradient(8, 6, {"R", "G", "B", "depth.Z", "id.ID"}, PixelType::Float), "exr");
    writeImageSeed(images, "rgba16.tif.bin", 2, gradient(8, 6, {"R", "G", "B", "A"}, PixelType::UInt16),
                   "tif");
    writeImageSeed(images, "rgb.jpg.bin", 3, gradient(8, 6, {"R", "G", "B"}, PixelType::UInt8), "jpg");
    // Command-line words, NUL-separated.
    const std::string words[] = {std::string("size\0") + "1920x1080" + std::string("\0threads\0", 9) + "2",
                                 std::string("lr\0", 3) + "2e-3" + std::string("\0repeat\0", 8) + "15",
                                 "0.84*ssim+0.16*l1", std::string("gate\0", 5) + "0.04"};
    for (size_t i = 0; i < std::size(words); ++i)
        writeText(root / "fuzz_cli_numbers" / ("words" + std::to_string(i)), words[i]);
    std::printf("seeds written under %s\n", root.string().c_str());
    return 0;
}
