// dejag's metrics against scikit-image on the committed golden pairs (tests/golden/make_metrics_golden.py),
// on every SIMD path this CPU has: SSIM within 1e-4, PSNR within 1e-3 dB (the tolerances).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "base/simd.h"
#include "data/image.h"
#include "data/metrics.h"
#include "tests/test_util.h"

namespace dejag {
namespace {

nlohmann::json loadExpected() {
    std::ifstream in(testing::sourcePath("tests/golden/metrics/expected.json"));
    return nlohmann::json::parse(in);
}

double expectedNumber(const nlohmann::json& value) {
    return value.is_string() ? std::numeric_limits<double>::infinity() : value.get<double>();
}

class MetricsGolden : public testing::SimdLevelTest {};

TEST_P(MetricsGolden, AgreesWithScikitImage) {
    const nlohmann::json expected = loadExpected();
    ASSERT_GE(expected["cases"].size(), 10u);
    for (const auto& [name, want] : expected["cases"].items()) {
        SCOPED_TRACE(name);
        const Image reference = readImage(testing::sourcePath("tests/golden/metrics/" + name + "_ref.png"));
        const Image test = readImage(testing::sourcePath("tests/golden/metrics/" + name + "_test.png"));
        const ImageMetrics got = compareImages(reference, test);
        EXPECT_EQ(got.dataRange, want["data_range"].get<double>());
        const double mse = want["mse"].get<double>();
        EXPECT_NEAR(got.mse, mse, 1e-6 * std::max(1.0, mse));
        EXPECT_NEAR(got.rmse, want["rmse"].get<double>(), 1e-6 * std::max(1.0, std::sqrt(mse)));
        const double psnr = expectedNumber(want["psnr"]), snr = expectedNumber(want["snr"]);
        if (std::isinf(psnr)) {
            EXPECT_TRUE(std::isinf(got.psnr) && got.psnr > 0);
            EXPECT_TRUE(std::isinf(got.snr) && got.snr > 0);
        } else {
            EXPECT_NEAR(got.psnr, psnr, 1e-3);
            EXPECT_NEAR(got.snr, snr, 1e-3);
        }
        EXPECT_NEAR(got.ssim, want["ssim"].get<double>(), 1e-4);
        ASSERT_EQ(got.ssimPerChannel.size(), want["ssim_channels"].size());
        for (size_t c = 0; c < got.ssimPerChannel.size(); ++c)
            EXPECT_NEAR(got.ssimPerChannel[c], want["ssim_channels"][c].get<double>(), 1e-4)
                << "channel " << c;
    }
}

TEST_P(MetricsGolden, SsimMapMatchesScikitImageIncludingBorders) {
    const nlohmann::json expected = loadExpected();
    const auto& mapInfo = expected["cases"]["edges"]["ssim_map"];
    const int width = mapInfo["width"], height = mapInfo["height"];
    std::vector<float> want(size_t(width) * height);
    std::ifstream in(testing::sourcePath("tests/golden/metrics/" + mapInfo["file"].get<std::string>()),
                     std::ios::binary);
    in.read(reinterpret_cast<char*>(want.data()), std::streamsize(want.size() * sizeof(float)));
    ASSERT_TRUE(in.good());

    const Image reference = readImage(testing::sourcePath("tests/golden/metrics/edges_ref.png"));
    const Image test = readImage(testing::sourcePath("tests/golden/metrics/edges_test.png"));
    const SsimResult got = structuralSimilarity(reference, test, 1.0, nullptr, true);
    ASSERT_EQ(got.map.size(), want.size());
    double worst = 0.0;
    for (size_t i = 0; i < want.size(); ++i) worst = std::max(worst, double(std::abs(got.map[i] - want[i])));
    // The map is float32: in bright flat regions of a high-contrast image, sigma^2 = E[x^2] - mean^2 keeps
    // ~1e-7 of absolute error, which C2 = 9e-4 turns into up to ~2e-4 of per-pixel SSIM. Means over many
    // pixels average it out (the mean SSIM above agrees to 1e-4, in practice ~1e-6).
    EXPECT_LE(worst, 5e-4) << "largest per-pixel SSIM difference";
    double meanDifference = 0.0;
    for (size_t i = 0; i < want.size(); ++i) meanDifference += double(got.map[i]) - double(want[i]);
    EXPECT_LE(std::abs(meanDifference) / double(want.size()), 1e-5) << "mean per-pixel SSIM difference";
}

INSTANTIATE_TEST_SUITE_P(SimdLevels, MetricsGolden, ::testing::ValuesIn(testing::availableSimdLevels()),
                         testing::simdTestName);

}  // namespace
}  // namespace dejag
