#include "train/bench_card.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

#include "base/error.h"

namespace dejag::train {
namespace {

using json = nlohmann::json;

// A figure of a row: a number, or the mean of a sequence test's {best, mean, worst}.
double figure(const json& row, const char* key) {
    const json& v = row.at(key);
    return v.is_object() ? v.at("mean").get<double>() : v.get<double>();
}

struct Mean {
    double psnr = 0, ssim = 0, flicker = 0;
    int count = 0;
    bool hasFlicker = false;
};

}  // namespace

BenchCardSection benchTaaSection(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw Error("--bench-taa: cannot read '" + path + "'");
    // Per test, the methods in the order they first appear, and their running sums.
    const std::vector<std::string> tests = {"static", "moving", "ghosting"};
    std::map<std::string, std::vector<std::string>> order;
    std::map<std::string, std::map<std::string, Mean>> means;
    std::vector<std::string> scenes;                                  // the static test's, in order
    std::map<std::string, std::map<std::string, double>> staticPsnr;  // [scene][method]
    std::string line, size;
    double spread = -1;  // the rows' jitter spread (older rows: not given)
    int number = 0, rows = 0;
    while (std::getline(in, line)) {
        ++number;
        if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
        json row;
        try {
            row = json::parse(line);
            const std::string test = row.at("test").get<std::string>();
            const std::string method = row.at("method").get<std::string>();
            if (std::find(tests.begin(), tests.end(), test) == tests.end()) continue;  // another row kind
            Mean& m = means[test][method];
            if (m.count == 0) order[test].push_back(method);
            m.psnr += figure(row, "psnr"), m.ssim += figure(row, "ssim"), ++m.count;
            if (row.contains("flicker")) m.flicker += row.at("flicker").get<double>(), m.hasFlicker = true;
            if (row.contains("jitter_spread")) spread = row.at("jitter_spread").get<double>();
            if (test == "static") {
                const std::string scene = row.at("scene").get<std::string>();
                if (!staticPsnr.count(scene)) scenes.push_back(scene);
                staticPsnr[scene][method] = figure(row, "psnr");
                size = std::to_string(row.at("width").get<int>()) + "x" +
                       std::to_string(row.at("height").get<int>());
            }
            ++rows;
        } catch (const json::exception& e) {
            throw Error("--bench-taa: '" + path + "' line " + std::to_string(number) +
                        " is not a row of `dejag bench taa --json` (" + e.what() + ")");
        }
    }
    if (rows == 0) throw Error("--bench-taa: '" + path + "' holds no row of `dejag bench taa --json`");

    BenchCardSection section;
    std::ostringstream md;
    char text[512];
    md << "## `dejag bench taa`\n\nThe benchmark's tests (docs/infer.md) on dejag's scenes, none of them "
          "in training; PSNR and SSIM against each frame's truth on 8-bit values; flicker on 8-bit values "
          "(docs/metrics.md). Each figure is the mean over the test's scenes (and motions)";
    if (spread >= 0) {
        std::snprintf(text, sizeof text, "; the frames' jitter spread %g px", spread);
        md << text;
    }
    md << ".\n";
    for (const std::string& test : tests) {
        if (!means.count(test)) continue;
        const bool flicker = means[test].begin()->second.hasFlicker;
        std::snprintf(text, sizeof text,
                      "\n### %s test%s\n\n| method | PSNR dB | SSIM |%s\n|---|---|---|%s\n", test.c_str(),
                      test == "static" ? (" (" + size + ")").c_str() : "", flicker ? " flicker |" : "",
                      flicker ? "---|" : "");
        md << text;
        for (const std::string& method : order[test]) {
            const Mean& m = means[test][method];
            json entry = {{"psnr", m.psnr / m.count}, {"ssim", m.ssim / m.count}, {"count", m.count}};
            if (m.hasFlicker) entry["flicker"] = m.flicker / m.count;
            section.summary[test][method] = entry;
            std::snprintf(text, sizeof text, "| %s | %.2f | %.4f |", method.c_str(), m.psnr / m.count,
                          m.ssim / m.count);
            md << text;
            if (flicker) {
                std::snprintf(text, sizeof text, " %.5f |", m.hasFlicker ? m.flicker / m.count : 0.0);
                md << text;
            }
            md << "\n";
        }
    }
    if (!scenes.empty()) {  // the static test scene by scene
        md << "\n### Static test, PSNR dB scene by scene\n\n| scene |";
        for (const std::string& method : order["static"]) md << " " << method << " |";
        md << "\n|---|";
        for (size_t k = 0; k < order["static"].size(); ++k) md << "---|";
        md << "\n";
        for (const std::string& scene : scenes) {
            md << "| " << scene << " |";
            for (const std::string& method : order["static"]) {
                const auto found = staticPsnr[scene].find(method);
                if (found == staticPsnr[scene].end()) {
                    md << " |";
                } else {
                    std::snprintf(text, sizeof text, " %.2f |", found->second);
                    md << text;
                }
            }
            md << "\n";
        }
    }
    section.markdown = md.str();
    return section;
}

}  // namespace dejag::train
