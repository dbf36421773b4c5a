#include "data/evaluation.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "base/error.h"
#include "base/luma.h"
#include "base/thread_pool.h"
#include "data/metrics.h"

namespace dejag::data {

namespace fs = std::filesystem;

namespace {

constexpr int kMinimumRegionPixels = 64;
constexpr float kDepthJump = 0.05f;         // relative inverse-depth miss that makes a geometric edge
constexpr int kTextureEdgeDistance = 3;     // texture pixels keep this far from geometric edges
constexpr float kTextureLumaRange = 0.04f;  // 3x3 truth luma range that counts as detail

// The first three colour channels as sRGB-encoded values in [0, 1].
Image encodedColour(const Image& image, const std::string& what) {
    const int r = image.findChannel("R");
    if (r < 0 || image.findChannel("G") != r + 1 || image.findChannel("B") != r + 2)
        throw Error(what + " has no R, G, B channels");
    Image out(image.width, image.height, {"R", "G", "B"}, PixelType::Float);
    const size_t channels = size_t(image.channels());
    for (size_t p = 0; p < image.pixelCount(); ++p)
        for (size_t c = 0; c < 3; ++c) {
            const float v = image.pixels[p * channels + size_t(r) + c];
            out.pixels[p * 3 + c] = std::clamp(linearToSrgb(std::max(v, 0.0f)), 0.0f, 1.0f);
        }
    return out;
}

float luma(const float* rgb) {
    return ::dejag::luma(rgb);
}

}  // namespace

const char* regionName(Region region) {
    static const char* const names[] = {"whole", "edge", "texture"};
    static_assert(std::size(names) == size_t(Region::Count));
    return names[int(region)];
}

Image lumaImage(const Image& rgb) {
    if (rgb.channels() < 3) throw Error("luma needs an RGB image, got " + rgb.describe());
    Image out(rgb.width, rgb.height, {"Y"}, rgb.storage);
    for (size_t p = 0; p < rgb.pixelCount(); ++p)
        out.pixels[p] = luma(&rgb.pixels[p * size_t(rgb.channels())]);
    return out;
}

EvaluationItem regionsOfFrame(const std::string& name, const std::vector<float>& truth, int width, int height,
                              const Image& buffers) {
    EvaluationItem item;
    item.id = name;
    item.truth = Image(width, height, Image::defaultChannelNames(3));
    item.truth.pixels = truth;
    computeRegionMasks(item, buffers);
    return item;
}

void computeRegionMasks(EvaluationItem& item, const Image& buffers) {
    const int W = item.truth.width, H = item.truth.height;
    const int id = buffers.findChannel("id.ID"), depth = buffers.findChannel("depth.Z");
    if (id < 0 || depth < 0) throw Error("item " + item.id + " has no id.ID and depth.Z buffers");
    std::vector<uint8_t> edge(size_t(W) * size_t(H), 0);
    // A depth jump between neighbours p and n = p + d: inverse depth (affine in screen space on any plane,
    // so planes seen at grazing angles are not edges) extrapolated linearly from either side misses the
    // other side by more than kDepthJump.
    auto inverseDepth = [&](int x, int y) { return 1.0f / std::max(buffers.at(x, y, depth), 1e-6f); };
    auto depthJump = [&](int x, int y, int dx, int dy) {
        const float w0 = inverseDepth(x, y), w1 = inverseDepth(x + dx, y + dy);
        const bool before = x - dx >= 0 && y - dy >= 0 && x - dx < W && y - dy < H;
        const bool after = x + 2 * dx < W && y + 2 * dy < H;
        const float fromBefore = before ? 2 * w0 - inverseDepth(x - dx, y - dy) : w0;
        const float fromAfter = after ? 2 * w1 - inverseDepth(x + 2 * dx, y + 2 * dy) : w1;
        return std::abs(fromBefore - w1) > kDepthJump * w1 && std::abs(fromAfter - w0) > kDepthJump * w0;
    };
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            for (const auto& [dx, dy] : {std::pair{1, 0}, std::pair{0, 1}}) {
                const int nx = x + dx, ny = y + dy;
                if (nx >= W || ny >= H) continue;
                if (buffers.at(x, y, id) != buffers.at(nx, ny, id) || depthJump(x, y, dx, dy)) {
                    edge[size_t(y) * size_t(W) + size_t(x)] = 1;
                    edge[size_t(ny) * size_t(W) + size_t(nx)] = 1;
                }
            }
    // Distance (Chebyshev, capped) to the nearest edge pixel, by two passes.
    const int cap = 1000;
    std::vector<int> distance(edge.size());
    for (size_t i = 0; i < edge.size(); ++i) distance[i] = edge[i] ? 0 : cap;
    auto at = [&](int x, int y) -> int& { return distance[size_t(y) * size_t(W) + size_t(x)]; };
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            for (const auto& [dx, dy] :
                 {std::pair{-1, 0}, std::pair{-1, -1}, std::pair{0, -1}, std::pair{1, -1}}) {
                const int nx = x + dx, ny = y + dy;
                if (nx >= 0 && ny >= 0 && nx < W) at(x, y) = std::min(at(x, y), at(nx, ny) + 1);
            }
    for (int y = H - 1; y >= 0; --y)
        for (int x = W - 1; x >= 0; --x)
            for (const auto& [dx, dy] :
                 {std::pair{1, 0}, std::pair{1, 1}, std::pair{0, 1}, std::pair{-1, 1}}) {
                const int nx = x + dx, ny = y + dy;
                if (nx >= 0 && nx < W && ny < H) at(x, y) = std::min(at(x, y), at(nx, ny) + 1);
            }
    const Image truthLuma = lumaImage(item.truth);
    int64_t counts[int(Region::Count)]{};
    for (int r = 0; r < int(Region::Count); ++r) item.masks[r] = Image(W, H, {"Y"}, PixelType::Float);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t p = size_t(y) * size_t(W) + size_t(x);
            float low = 1e30f, high = -1e30f;
            for (int j = std::max(0, y - 1); j <= std::min(H - 1, y + 1); ++j)
                for (int i = std::max(0, x - 1); i <= std::min(W - 1, x + 1); ++i) {
                    const float v = truthLuma.pixels[size_t(j) * size_t(W) + size_t(i)];
                    low = std::min(low, v), high = std::max(high, v);
                }
            const bool inRegion[] = {true, distance[p] <= 1,
                                     distance[p] >= kTextureEdgeDistance && high - low > kTextureLumaRange};
            for (int r = 0; r < int(Region::Count); ++r) {
                item.masks[r].pixels[p] = inRegion[r] ? 1.0f : 0.0f;
                counts[r] += inRegion[r];
            }
        }
    for (int r = 0; r < int(Region::Count); ++r) item.hasRegion[r] = counts[r] >= kMinimumRegionPixels;
}

std::vector<EvaluationItem> loadEvaluationItems(const std::string& folder, Split split, int limit,
                                                const std::vector<std::string>& families) {
    std::vector<nlohmann::json> records;
    for (nlohmann::json& record : readManifest(folder))
        if (record.value("split", "") == splitName(split) &&
            (families.empty() ||
             std::find(families.begin(), families.end(), record.value("family", "")) != families.end()))
            records.push_back(std::move(record));
    if (records.empty())
        throw Error("'" + folder + "' has no " + std::string(splitName(split)) + " items to evaluate on");
    std::vector<size_t> chosen;
    if (limit <= 0 || size_t(limit) >= records.size()) {
        for (size_t i = 0; i < records.size(); ++i) chosen.push_back(i);
    } else {
        for (int i = 0; i < limit; ++i) chosen.push_back(size_t(i) * records.size() / size_t(limit));
    }
    std::vector<EvaluationItem> items(chosen.size());
    parallelFor(0, int64_t(chosen.size()), 1, [&](int64_t first, int64_t last) {
        for (int64_t k = first; k < last; ++k) {
            const nlohmann::json& record = records[chosen[size_t(k)]];
            EvaluationItem& item = items[size_t(k)];
            item.index = record.at("index").get<int>();
            item.id = record.at("id").get<std::string>();
            item.family = record.at("family").get<std::string>();
            const Image input =
                readImage((fs::path(folder) / record["files"]["input"]["path"].get<std::string>()).string());
            const Image truth =
                readImage((fs::path(folder) / record["files"]["truth"]["path"].get<std::string>()).string());
            if (input.width != truth.width || input.height != truth.height)
                throw Error("item " + item.id + ": input and truth differ in size");
            item.input = encodedColour(input, "item " + item.id + " input");
            item.truth = encodedColour(truth, "item " + item.id + " truth");
            computeRegionMasks(item, input);
        }
    });
    return items;
}

ImageScore scoreImage(const EvaluationItem& item, const Image& output) {
    if (output.width != item.truth.width || output.height != item.truth.height)
        throw Error("output " + output.describe() + " does not match item " + item.id);
    Image grey;
    const Image* reference = &item.truth;
    if (output.channels() == 1) {
        grey = lumaImage(item.truth);
        reference = &grey;
    } else if (output.channels() != 3) {
        throw Error("scoring needs 1 or 3 channels, got " + output.describe());
    }
    ImageScore score;
    // A non-finite output is the worst score there is, never a perfect one (a NaN error compared as no
    // error at all): PSNR 0 dB and SSIM -1 on every region, and the image is counted as non-finite.
    const bool finite =
        std::all_of(output.pixels.begin(), output.pixels.end(), [](float v) { return std::isfinite(v); });
    if (!finite) {
        score.nonFinite = true;
        for (int r = 0; r < int(Region::Count); ++r)
            if (item.hasRegion[r]) score.region[r] = {kWorstPsnr, -1.0, true};
        return score;
    }
    for (int r = 0; r < int(Region::Count); ++r) {
        if (!item.hasRegion[r]) continue;
        MetricOptions options;
        options.dataRange = 1.0;
        options.mask = r == int(Region::Whole) ? nullptr : &item.masks[r];
        try {
            const ImageMetrics m = compareImages(*reference, output, options);
            score.region[r] = {m.psnr, m.ssim, true};
        } catch (const Error&) {
            // The region lies entirely in the border SSIM crops away: not scored for this image.
        }
    }
    return score;
}

void ScoreSummary::add(const ImageScore& score) {
    nonFiniteImages += score.nonFinite;
    for (int r = 0; r < int(Region::Count); ++r) {
        if (!score.region[r].scored) continue;
        // An identical region has infinite PSNR; cap it so one perfect image does not swamp the mean.
        psnr[r] += std::min(score.region[r].psnr, 100.0);
        ssim[r] += score.region[r].ssim;
        ++images[r];
    }
}

void ScoreSummary::finish() {
    for (int r = 0; r < int(Region::Count); ++r)
        if (images[r] > 0)
            psnr[r] /= images[r], ssim[r] /= images[r];
        else
            psnr[r] = ssim[r] = std::nan("");  // no image has this region
}

}  // namespace dejag::data
