// dejag/train: a model card's section from the rows `dejag bench taa --json` printed (one JSON object a
// line): per test, each method's mean over the test's scenes (and motions), and the static test scene by
// scene, so the card carries the benchmark's table next to the scores of the splits.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace dejag::train {

struct BenchCardSection {
    std::string markdown;    // "## bench taa" and its tables
    nlohmann::json summary;  // {test: {method: {psnr, ssim[, flicker], count}}}
};

// Reads the rows of `path`. A missing or unreadable file, a line that is not a JSON object of a bench taa
// row, or no row at all: an Error naming the file and the line.
BenchCardSection benchTaaSection(const std::string& path);

}  // namespace dejag::train
