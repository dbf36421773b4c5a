// Fuzz target: what the command line turns into numbers — frame sizes (WIDTHxHEIGHT), comma lists,
// loss specs (0.84*ssim+0.16*l1) — and CLI11's own integer and float options with their range checks,
// as the subcommands declare them, behind the guard main() puts on every option (no NaN or infinity in a
// float, no negative number in an unsigned one). The input is split at NUL bytes into the strings tried.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "app/cli.h"
#include "base/error.h"
#include "nn/losses.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    std::vector<std::string> words(1);
    for (size_t i = 0; i < size && words.size() < 8; ++i) {
        if (data[i] == 0)
            words.emplace_back();
        else
            words.back() += char(data[i]);
    }
    for (const std::string& word : words) {
        try {
            (void)dejag::cli::parseSize(word, "--size");
        } catch (const dejag::Error&) {
        }
        (void)dejag::cli::splitList(word);
        try {
            (void)dejag::nn::CompositeLoss::parse(word);
        } catch (const dejag::Error&) {
        }
    }
    CLI::App app("fuzz");
    int threads = 0, repeat = 15;
    double lr = 1e-3, gate = 0.04;
    std::string frameSize = "1920x1080";
    app.add_option("--threads", threads)->check(CLI::Range(0, 256));
    app.add_option("--repeat", repeat)->check(CLI::Range(1, 10000));
    app.add_option("--lr", lr)->check(CLI::PositiveNumber);
    app.add_option("--gate", gate);
    app.add_option("--size", frameSize);
    uint64_t seed = 1;
    app.add_option("--seed", seed);
    dejag::cli::guardNumericOptions(app);
    std::vector<std::string> args;
    for (size_t i = 0; i < words.size(); ++i) args.push_back((i % 2 == 0 ? "--" : "") + words[i]);
    std::reverse(args.begin(), args.end());  // CLI11 parses a vector from the back
    try {
        app.parse(args);
        // What the guard promises: no NaN or infinity gets into a float option.
        if (!std::isfinite(lr) || !std::isfinite(gate)) __builtin_trap();
        if (!frameSize.empty()) (void)dejag::cli::parseSize(frameSize, "--size");
    } catch (const CLI::Error&) {
    } catch (const dejag::Error&) {
    }
    return 0;
}
