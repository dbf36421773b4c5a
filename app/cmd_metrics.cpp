// dejag metrics REF TEST: MSE, RMSE, PSNR, SNR and SSIM of a test image against its reference; for two
// sequences, each frame's figures, the best, worst and mean frame and the flicker (docs/metrics.md).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>

#include "app/cli.h"
#include "app/commands.h"
#include "app/sequence.h"
#include "base/error.h"
#include "data/image.h"
#include "data/metrics.h"
#include "data/spectrum.h"
#include "data/video.h"

namespace dejag::cli {
namespace {

struct MetricsArguments {
    std::string reference, test, mask, ssimMap, space = "auto";
    std::string shownReference, shownTest;  // as the user named them ("-" for standard input)
    double dataRange = 0.0;
    bool json = false, aliasing = false;
    RuntimeOptions runtime;
};

Image readScoredImage(const std::string& path) {
    Image image = readImage(path);
    if (auto bad = findNonFinite(image))
        throw Error("'" + path + "' has a non-finite value (" +
                    std::to_string(image.at(bad->x, bad->y, bad->channel)) + ") at pixel (" +
                    std::to_string(bad->x) + ", " + std::to_string(bad->y) + "), channel " +
                    image.channelNames[bad->channel]);
    return image;
}

const char* spaceOf(const Image& image) {
    return holdsLinearLight(image.storage) ? "linear light" : "sRGB-encoded values";
}

// Like is compared with like: an EXR holds linear light, a PNG sRGB-encoded values, and the error between
// the two encodings of one frame is no measure of anything. Mixed inputs are refused unless --space names
// the space to score in; then each image is converted into it (colour channels only). Returns the note the
// report prints ("" when nothing was converted).
std::string bringIntoOneSpace(Image& reference, Image& test, const std::string& referencePath,
                              const std::string& testPath, const MetricsArguments& args) {
    const bool referenceLinear = holdsLinearLight(reference.storage),
               testLinear = holdsLinearLight(test.storage);
    if (args.space == "auto") {
        if (referenceLinear == testLinear) return "";
        throw Error("'" + referencePath + "' holds " + spaceOf(reference) + " and '" + testPath + "' " +
                    spaceOf(test) + "; score them in one space with --space srgb or --space linear");
    }
    const bool linear = args.space == "linear";
    std::string converted;
    for (auto [image, path] : {std::pair{&reference, &referencePath}, std::pair{&test, &testPath}}) {
        if (holdsLinearLight(image->storage) == linear) continue;
        if (linear)
            convertSrgbToLinear(*image);
        else
            convertLinearToSrgb(*image);
        converted += (converted.empty() ? "'" : ", '") + *path + "'";
    }
    // The scale follows the space: linear light on its raw values (data range 1), sRGB on the integer
    // scale of whichever file had one.
    const PixelType scale = linear                                 ? PixelType::Float
                            : !holdsLinearLight(reference.storage) ? reference.storage
                            : !holdsLinearLight(test.storage)      ? test.storage
                                                                   : PixelType::Float;
    if (linear || referenceLinear != testLinear) reference.storage = test.storage = scale;
    return converted.empty() ? "" : converted + (linear ? " decoded to linear light" : " encoded to sRGB");
}

std::string formatDecibels(double value) {
    if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
    char text[64];
    std::snprintf(text, sizeof text, "%.4f dB", value);
    return text;
}

// One pair scored: both images as scored (in one space, on the channels they share) and the figures.
struct ScoredPair {
    Image reference, test;
    std::string referenceDescription, testDescription, spaceNote, matchedNote;
    ImageMetrics metrics;
};

ScoredPair scoreImages(Image referenceImage, Image testImage, const std::string& referencePath,
                       const std::string& testPath, const MetricsArguments& args, const Image* mask,
                       bool wantSsimMap) {
    ScoredPair r;
    Image& reference = r.reference;
    Image& test = r.test;
    reference = std::move(referenceImage);
    test = std::move(testImage);
    r.referenceDescription = reference.describe(), r.testDescription = test.describe();
    r.spaceNote = bringIntoOneSpace(reference, test, referencePath, testPath, args);
    if (reference.width != test.width || reference.height != test.height)
        throw Error("'" + testPath + "' is " + std::to_string(test.width) + "x" +
                    std::to_string(test.height) + " but '" + referencePath + "' is " +
                    std::to_string(reference.width) + "x" + std::to_string(reference.height));
    // Different channel counts: score the channels the two share by name (a dataset input holds R, G, B
    // and its G-buffers, its truth R, G, B), if one image holds all the other's.
    if (reference.channels() != test.channels()) {
        const auto holdsAll = [](const Image& image, const std::vector<std::string>& names) {
            for (const std::string& name : names)
                if (image.findChannel(name) < 0) return false;
            return true;
        };
        if (holdsAll(test, reference.channelNames)) {
            r.matchedNote = "channels " + reference.channelList() + " of the test image's " +
                            std::to_string(test.channels());
            test = selectChannels(test, reference.channelNames);
        } else if (holdsAll(reference, test.channelNames)) {
            r.matchedNote = "channels " + test.channelList() + " of the reference's " +
                            std::to_string(reference.channels());
            reference = selectChannels(reference, test.channelNames);
        } else {
            throw Error("'" + testPath + "' has " + std::to_string(test.channels()) + " channels (" +
                        test.channelList() + ") but '" + referencePath + "' has " +
                        std::to_string(reference.channels()) + " (" + reference.channelList() +
                        "), and neither holds all the other's");
        }
    }
    if (mask && (mask->width != reference.width || mask->height != reference.height))
        throw Error("mask '" + args.mask + "' is " + std::to_string(mask->width) + "x" +
                    std::to_string(mask->height) + " but the images are " + std::to_string(reference.width) +
                    "x" + std::to_string(reference.height));
    MetricOptions options;
    options.dataRange = args.dataRange;
    options.mask = mask;
    options.wantSsimMap = wantSsimMap;
    r.metrics = compareImages(reference, test, options);
    return r;
}

ScoredPair scorePair(const std::string& referencePath, const std::string& testPath,
                     const MetricsArguments& args, const Image* mask, bool wantSsimMap) {
    return scoreImages(readScoredImage(referencePath), readScoredImage(testPath), referencePath, testPath,
                       args, mask, wantSsimMap);
}

// The frames of one side of a sequence comparison: a folder or pattern of images, or a video.
class FrameSource {
  public:
    explicit FrameSource(const std::string& path) : path_(path) {
        if (isVideoPath(path))
            video_ = std::make_unique<VideoReader>(path);
        else
            frames_ = listSequence(path);
    }
    bool isVideo() const { return video_ != nullptr; }
    const std::vector<SequenceFrame>& frames() const { return frames_; }
    // Frame `index` of a video, read in order (each once).
    bool readVideoFrame(Image& image, std::string& label) {
        if (!video_->read(image)) return false;
        label = path_ + " frame " + std::to_string(video_->framesRead() - 1);
        return true;
    }
    int64_t videoFramesRead() const { return video_->framesRead(); }

  private:
    std::string path_;
    std::unique_ptr<VideoReader> video_;
    std::vector<SequenceFrame> frames_;
};

void runSequenceMetrics(const MetricsArguments& args, const Image* mask);

void runMetrics(const MetricsArguments& args) {
    applyRuntimeOptions(args.runtime);
    std::optional<Image> mask;
    if (!args.mask.empty()) mask = readImage(args.mask);
    const bool referenceSequence = isSequence(args.reference) || isVideoPath(args.reference),
               testSequence = isSequence(args.test) || isVideoPath(args.test);
    if (referenceSequence || testSequence) {
        if (!(referenceSequence && testSequence))
            throw Error(
                "'" + (referenceSequence ? args.reference : args.test) + "' is a sequence and '" +
                (referenceSequence ? args.test : args.reference) +
                "' one image: give two sequences (videos, folders or patterns such as f_%04d.png) or two "
                "images");
        if (!args.ssimMap.empty()) throw Error("--ssim-map takes one image pair, not a sequence");
        if (args.aliasing) throw Error("--aliasing takes one image pair, not a sequence");
        runSequenceMetrics(args, mask ? &*mask : nullptr);
        return;
    }
    const ScoredPair scored =
        scorePair(args.reference, args.test, args, mask ? &*mask : nullptr, !args.ssimMap.empty());
    const Image& reference = scored.reference;
    const ImageMetrics& metrics = scored.metrics;
    const std::string &referenceDescription = scored.referenceDescription,
                      &testDescription = scored.testDescription, &spaceNote = scored.spaceNote,
                      &matchedNote = scored.matchedNote;
    if (!args.ssimMap.empty())
        writeSsimMapPng(args.ssimMap, metrics.ssimMap, reference.width, reference.height);
    std::optional<AliasingScore> aliasing;
    if (args.aliasing) aliasing = aliasingScore(scored.test, scored.reference);

    if (args.json) {
        nlohmann::json out;
        out["reference"] = args.shownReference;
        out["test"] = args.shownTest;
        out["width"] = reference.width;
        out["height"] = reference.height;
        out["channels"] = reference.channelNames;
        out["matched_by_name"] = !matchedNote.empty();
        out["space"] = holdsLinearLight(reference.storage) ? "linear" : "srgb";
        out["converted"] = !spaceNote.empty();
        out["pixel_type"] = pixelTypeName(reference.storage);
        out["value_scale"] = metrics.valueScale;
        out["data_range"] = metrics.dataRange;
        out["mse"] = metrics.mse;
        out["rmse"] = metrics.rmse;
        // Identical images: PSNR and SNR are infinite, which JSON cannot hold; null plus "identical".
        out["psnr"] = std::isinf(metrics.psnr) ? nlohmann::json(nullptr) : nlohmann::json(metrics.psnr);
        out["snr"] = std::isinf(metrics.snr) ? nlohmann::json(nullptr) : nlohmann::json(metrics.snr);
        out["identical"] = metrics.mse == 0.0;
        out["ssim"] = metrics.ssim;
        nlohmann::json perChannel = nlohmann::json::object();
        for (int c = 0; c < reference.channels(); ++c)
            perChannel[reference.channelNames[c]] = metrics.ssimPerChannel[c];
        out["ssim_channels"] = perChannel;
        out["pixels"] = metrics.scoredPixels;
        out["ssim_pixels"] = metrics.ssimScoredPixels;
        out["mask"] = args.mask.empty() ? nlohmann::json(nullptr) : nlohmann::json(args.mask);
        out["ssim_map"] = args.ssimMap.empty() ? nlohmann::json(nullptr) : nlohmann::json(args.ssimMap);
        if (aliasing) {
            out["aliasing"] = aliasing->aliasing;
            out["aliasing_db"] = std::isinf(aliasing->aliasingDb()) ? nlohmann::json(nullptr)
                                                                    : nlohmann::json(aliasing->aliasingDb());
            out["detail_kept"] = aliasing->detailKept;
        }
        std::printf("%s\n", out.dump().c_str());
        return;
    }
    std::printf("reference  %s  (%s)\n", args.shownReference.c_str(), referenceDescription.c_str());
    std::printf("test       %s  (%s)\n", args.shownTest.c_str(), testDescription.c_str());
    if (!matchedNote.empty()) std::printf("scored     %s, matched by name\n", matchedNote.c_str());
    if (!spaceNote.empty()) std::printf("space      %s\n", spaceNote.c_str());
    std::printf(
        "scale      0-%g, data range %g%s\n", metrics.valueScale, metrics.dataRange,
        mask ? (", masked by " + args.mask + " (" + std::to_string(metrics.scoredPixels) + " pixels)").c_str()
             : "");
    std::printf("MSE        %.6f\n", metrics.mse);
    std::printf("RMSE       %.6f\n", metrics.rmse);
    std::printf("PSNR       %s\n", formatDecibels(metrics.psnr).c_str());
    std::printf("SNR        %s\n", formatDecibels(metrics.snr).c_str());
    std::printf("SSIM       %.6f  (", metrics.ssim);
    for (int c = 0; c < reference.channels(); ++c)
        std::printf("%s%s %.6f", c ? ", " : "", reference.channelNames[c].c_str(), metrics.ssimPerChannel[c]);
    std::printf(")\n");
    if (!args.ssimMap.empty()) std::printf("SSIM map   %s\n", args.ssimMap.c_str());
    if (aliasing)
        std::printf("aliasing   %.6f (%s of the reference's spectral energy), detail kept %.4f\n",
                    aliasing->aliasing, formatDecibels(aliasing->aliasingDb()).c_str(), aliasing->detailKept);
}

// Two sequences, frame by frame (paired by frame number when both are numbered, else in order): each
// frame's figures, then the mean, best and worst frame and the flicker (docs/metrics.md).
void runSequenceMetrics(const MetricsArguments& args, const Image* mask) {
    FrameSource referenceSource(args.reference), testSource(args.test);
    struct Row {
        std::string reference, test;
        long number;
        ImageMetrics metrics;
        double flicker;  // against the frame before (-1 for the first)
    };
    std::vector<Row> rows;
    std::vector<float> previousReference, previousTest;
    double flickerSum = 0;
    const auto score = [&](ScoredPair scored, const std::string& referenceLabel, const std::string& testLabel,
                           long number) {
        double flicker = -1;
        if (!previousTest.empty()) {
            if (previousTest.size() != scored.test.pixels.size())
                throw Error("'" + testLabel + "' is not the size of the frame before it");
            // (X_t - X_t-1) - (R_t - R_t-1), on the images' value scale, over the scored pixels
            double sum = 0;
            size_t count = 0;
            const size_t C = size_t(scored.test.channels());
            for (size_t i = 0; i < scored.test.pixels.size(); ++i) {
                if (mask && mask->pixels[(i / C) * size_t(mask->channels())] <= 0.5f) continue;
                sum += std::abs(double(scored.test.pixels[i] - previousTest[i]) -
                                double(scored.reference.pixels[i] - previousReference[i]));
                ++count;
            }
            flicker = count ? sum / double(count) : 0.0;  // on the [0, 1] scale of integer images
            flickerSum += flicker;
        }
        previousTest = std::move(scored.test.pixels), previousReference = std::move(scored.reference.pixels);
        rows.push_back({referenceLabel, testLabel, number, scored.metrics, flicker});
    };
    if (referenceSource.isVideo() || testSource.isVideo()) {
        // A video on either side: frames paired in order, from 0; both must end together.
        size_t index = 0;
        for (;; ++index) {
            Image reference, test;
            std::string referenceLabel, testLabel;
            bool haveReference, haveTest;
            if (referenceSource.isVideo()) {
                haveReference = referenceSource.readVideoFrame(reference, referenceLabel);
            } else if ((haveReference = index < referenceSource.frames().size())) {
                referenceLabel = referenceSource.frames()[index].path;
                reference = readScoredImage(referenceLabel);
            }
            if (testSource.isVideo()) {
                haveTest = testSource.readVideoFrame(test, testLabel);
            } else if ((haveTest = index < testSource.frames().size())) {
                testLabel = testSource.frames()[index].path;
                test = readScoredImage(testLabel);
            }
            if (!haveReference && !haveTest) break;
            if (haveReference != haveTest)
                throw Error("'" + (haveReference ? args.test : args.reference) + "' ends after " +
                            std::to_string(index) + " frames, and '" +
                            (haveReference ? args.reference : args.test) + "' holds more");
            score(scoreImages(std::move(reference), std::move(test), referenceLabel, testLabel, args, mask,
                              false),
                  referenceLabel, testLabel, long(index));
        }
        if (index == 0) throw Error("'" + args.reference + "' holds no frames");
    } else {
        const std::vector<SequenceFrame>&references = referenceSource.frames(), &tests = testSource.frames();
        std::vector<std::pair<const SequenceFrame*, const SequenceFrame*>> pairs;
        const bool numbered =
            std::all_of(references.begin(), references.end(),
                        [](const SequenceFrame& f) { return f.number >= 0; }) &&
            std::all_of(tests.begin(), tests.end(), [](const SequenceFrame& f) { return f.number >= 0; });
        if (numbered) {
            for (const SequenceFrame& t : tests) {
                const auto r = std::find_if(references.begin(), references.end(),
                                            [&](const SequenceFrame& f) { return f.number == t.number; });
                if (r == references.end())
                    throw Error("'" + t.path + "' is frame " + std::to_string(t.number) + ", which '" +
                                args.reference + "' does not hold");
                pairs.push_back({&*r, &t});
            }
        } else {
            if (references.size() != tests.size())
                throw Error("'" + args.reference + "' holds " + std::to_string(references.size()) +
                            " frames and '" + args.test + "' " + std::to_string(tests.size()));
            for (size_t i = 0; i < tests.size(); ++i) pairs.push_back({&references[i], &tests[i]});
        }
        for (const auto& [r, t] : pairs)
            score(scorePair(r->path, t->path, args, mask, false), r->path, t->path, t->number);
    }
    double psnrSum = 0, ssimSum = 0, psnrBest = -1e300, psnrWorst = 1e300, ssimWorst = 1e300;
    for (const Row& row : rows) {
        const double p = std::isinf(row.metrics.psnr) ? 1e3 : row.metrics.psnr;
        psnrSum += p, ssimSum += row.metrics.ssim;
        psnrBest = std::max(psnrBest, p), psnrWorst = std::min(psnrWorst, p);
        ssimWorst = std::min(ssimWorst, row.metrics.ssim);
    }
    const double n = double(rows.size()), flickerMean = rows.size() > 1 ? flickerSum / (n - 1) : 0.0;
    auto decibels = [](double v) { return std::isinf(v) ? nlohmann::json(nullptr) : nlohmann::json(v); };
    if (args.json) {
        for (const Row& row : rows)
            std::printf("%s\n", nlohmann::json{{"reference", row.reference},
                                               {"test", row.test},
                                               {"frame", row.number},
                                               {"mse", row.metrics.mse},
                                               {"psnr", decibels(row.metrics.psnr)},
                                               {"ssim", row.metrics.ssim},
                                               {"flicker", row.flicker < 0 ? nlohmann::json(nullptr)
                                                                           : nlohmann::json(row.flicker)}}
                                    .dump()
                                    .c_str());
        std::printf("%s\n", nlohmann::json{{"summary", true},
                                           {"frames", rows.size()},
                                           {"psnr_mean", psnrSum / n},
                                           {"psnr_best", psnrBest},
                                           {"psnr_worst", psnrWorst},
                                           {"ssim_mean", ssimSum / n},
                                           {"ssim_worst", ssimWorst},
                                           {"flicker", flickerMean}}
                                .dump()
                                .c_str());
        return;
    }
    std::printf("%-8s %12s %10s %12s\n", "frame", "PSNR dB", "SSIM", "flicker");
    for (const Row& row : rows) {
        std::printf("%-8ld %12s %10.6f ", row.number, formatDecibels(row.metrics.psnr).c_str(),
                    row.metrics.ssim);
        if (row.flicker < 0)
            std::printf("%12s\n", "-");
        else
            std::printf("%12.6f\n", row.flicker);
    }
    std::printf(
        "%zu frames: PSNR mean %.4f dB (best %.4f, worst %.4f), SSIM mean %.6f (worst %.6f), flicker %.6f\n",
        rows.size(), psnrSum / n, psnrBest, psnrWorst, ssimSum / n, ssimWorst, flickerMean);
}

}  // namespace

void registerMetricsCommand(CLI::App& app) {
    auto args = std::make_shared<MetricsArguments>();
    CLI::App* command =
        app.add_subcommand("metrics", "score TEST against REF: MSE, RMSE, PSNR, SNR, SSIM (docs/metrics.md)");
    command->footer(
        "8-bit images are scored on the 0-255 scale (data range 255), 16-bit on 0-65535, float on their raw\n"
        "values with data range 1 unless --data-range is given. SSIM: 11x11 Gaussian window (sigma 1.5),\n"
        "K1 0.01, K2 0.03, mean over pixels 5 or more from the border, colour = mean of per-channel SSIM.\n"
        "Identical images: PSNR and SNR are infinite (printed 'inf'; in JSON null, with \"identical\": "
        "true).\n"
        "Images with different channel counts are scored on the channels they share by name when one holds\n"
        "all the other's: a dataset input (R, G, B and its G-buffers) against its truth (R, G, B).\n"
        "A PNG/JPEG holds sRGB-encoded values, an EXR linear light: mixing them needs --space srgb|linear.\n"
        "Two sequences (folders or patterns such as out/f_%04d.png) are scored frame by frame, paired by\n"
        "frame number (a video, .mp4 .mov .mkv .avi, on either side: in order): each frame's PSNR and SSIM, "
        "the mean, best and worst frame, and the flicker: the "
        "mean\n"
        "|(X_t - X_t-1) - (R_t - R_t-1)| over consecutive frames, an 8- or 16-bit image's values taken\n"
        "as 0-1.");
    command
        ->add_option("REF", args->reference,
                     "reference image (the truth), or a sequence: video, folder or pattern; - reads standard "
                     "input")
        ->required();
    command
        ->add_option("TEST", args->test,
                     "image to score, or a sequence: video, folder or pattern (f_%04d.png); - reads standard "
                     "input")
        ->required();
    command->add_flag("--json", args->json, "print one JSON object (keys mse, rmse, psnr, snr, ssim, ...)");
    command->add_option("--ssim-map", args->ssimMap, "write the per-pixel SSIM map as a colour-mapped PNG");
    command->add_flag(
        "--aliasing", args->aliasing,
        "also the aliasing: the energy of TEST's spectrum that no smooth filtering of REF explains, "
        "and the detail kept (docs/metrics.md)");
    command->add_option("--mask", args->mask,
                        "score only pixels whose mask value is above 0.5 (first channel)");
    command
        ->add_option("--data-range", args->dataRange, "data range L on the reported scale (default: by type)")
        ->check(CLI::Validator(
            [](std::string& text) {
                return std::strtod(text.c_str(), nullptr) > 0 ? std::string()
                                                              : "must be above 0, not " + text;
            },
            "> 0", "positive"));
    command
        ->add_option("--space", args->space,
                     "auto (both files must hold one kind: sRGB PNG/JPEG or linear EXR), srgb or linear: "
                     "the space to score mixed inputs in")
        ->check(CLI::IsMember({"auto", "srgb", "linear"}))
        ->capture_default_str();
    addRuntimeOptions(command, args->runtime);
    command->callback([args] {
        // "-": one of the two images from standard input.
        if (args->reference == "-" && args->test == "-") throw Error("REF and TEST cannot both be '-'");
        StandardStreams streams;
        MetricsArguments given = *args;
        given.shownReference = args->reference, given.shownTest = args->test;
        given.reference = streams.input(args->reference);
        given.test = streams.input(args->test);
        runMetrics(given);
    });
}

}  // namespace dejag::cli
