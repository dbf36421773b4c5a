// dejag/bench: run time against error — every method scored on the same frames against their truth,
// with the report shared by `dejag demo` and `dejag bench quality`.
//
// A case is one frame (sRGB RGB in [0, 1]) with its truth and region masks (data/evaluation.h) and,
// when rendered, its depth and ID buffers (the CNN's gate uses them). Single-frame methods: no AA, FXAA
// (presets), each network gated and ungated, and chains (FXAA then the network). Sequence methods
// (U-TAA, T-TAA) are added by the caller when the case has a sequence.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "data/evaluation.h"
#include "data/image.h"

namespace dejag::bench {

struct MethodResult {
    std::string name;
    Image output;            // sRGB RGB, float
    double ms = 0;           // median per frame at the case's size
    data::ImageScore score;  // filled by scoreCase()
    std::string note;        // "gated: 42 % of tiles"
};

struct QualityCase {
    std::string name;
    bool heldOut = false;  // from a family no network trained on
    data::EvaluationItem item;
    std::vector<float> depth, ids;  // (H, W) each, or empty
    std::vector<MethodResult> methods;
    bool inReport = true;  // crops and SSIM maps in the HTML report
};

// The single-frame methods, built once (models loaded and checked up front).
class StillMethods {
  public:
    struct Options {
        std::vector<std::string> models;  // model files; missing ones are noted and skipped
        std::vector<int> fxaaPresets = {39};
        bool ungated = true;  // RGB networks also without gating
        bool chains = false;  // FXAA 39 then each network
        // Where the CPU has AVX-512 BF16: each RGB network also with bf16 activations ("NAME bf16",
        // gated and ungated), next to the float rows (nn/inference.h).
        bool bf16 = true;
    };
    explicit StillMethods(const Options& options);
    ~StillMethods();
    const std::vector<std::string>& notes() const;
    std::vector<std::string> names() const;
    // Runs every method on the case (one warm-up run, then the median of `repeat` timed runs).
    void run(QualityCase& c, int repeat);
    // Median ms per method on a frame of any size (sRGB RGB), e.g. 1920x1080; same order as names().
    std::vector<double> time(const Image& frame, const float* depth, const float* ids, int repeat);

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

// Scores every method of the case on every region.
void scoreCase(QualityCase& c);

// A crop of a frame: the window (of the crop's size) where `input` is furthest from the truth, and that
// window of an image enlarged `zoom` times (nearest pixel).
struct Window {
    int x = 0, y = 0, width = 0, height = 0;
};
Window worstWindow(const Image& input, const Image& truth, int width, int height);
Image zoomedCrop(const Image& image, const Window& w, int zoom);

struct ReportOptions {
    std::string out;    // folder: report.html, mosaic.png, pareto.png, results.csv, results.json, images/
    std::string title;  // of the report
    std::string intro;  // HTML paragraph under the title
    std::vector<std::string> notes;
    // Optional: method -> ms at 1920x1080 (the median over fullHdScenes), and each scene's ms.
    std::vector<std::pair<std::string, double>> fullHdMs;
    std::vector<std::string> fullHdScenes;
    std::map<std::string, std::vector<double>> fullHdSceneMs;  // method -> ms per scene, in that order
    std::string extraHtml;                                     // a section of its own, before the mosaic
};
// Writes the report from scored cases; returns one JSON row per (case, method) and a "mean" row per
// method (means over cases, ms a median; plus ms_1080p when given).
std::vector<nlohmann::json> writeQualityReport(const ReportOptions& options,
                                               const std::vector<QualityCase>& cases);

// The shipped models, as `dejag demo` and `dejag bench quality` look for them by default.
inline constexpr const char* kShippedModels =
    "models/dejag-fast.safetensors,models/dejag-guided.safetensors,models/seed2020-gray.safetensors";

// Prints rows as JSON lines, or as a table (the "mean" rows only, or all rows).
void printQualityRows(const std::vector<nlohmann::json>& rows, bool json, bool meansOnly);

// `dejag bench quality`: the test split of a dataset (and/or a folder of pairs NAME_input.* +
// NAME_truth.*), every single-frame method, timing at native size and at 1920x1080.
struct QualityBenchOptions {
    std::string data;   // dataset folder ("" to skip)
    std::string pairs;  // folder of pairs ("" to skip)
    std::string out = "out/quality";
    std::vector<std::string> models;
    int limit = 0;  // test items (0: all)
    int repeat = 3;
    int reportItems = 8;  // cases with crops in the report
    bool fullHd = true;   // time every method on the test scenes rendered at 1920x1080
    bool quiet = false;
};
std::vector<nlohmann::json> benchQuality(const QualityBenchOptions& options);

}  // namespace dejag::bench
