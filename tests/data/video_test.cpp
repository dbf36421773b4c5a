// Video files (data/video.h): lossless round trips, the frame rate kept, atomic writes, one-line refusals.
#include "data/video.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "base/error.h"
#include "tests/test_util.h"

namespace dejag {
namespace {

// Frame `t` of a moving 8-bit pattern: a slanted edge that slides one pixel a frame over a gradient.
Image movingEdge(int width, int height, int t) {
    Image image(width, height, {"R", "G", "B"}, PixelType::UInt8);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const bool bright = (x - t) * 3 > y * 2;
            image.at(x, y, 0) = bright ? 1.0f : float(x % 256) / 255.0f;
            image.at(x, y, 1) = bright ? float((y * 5) % 256) / 255.0f : 0.0f;
            image.at(x, y, 2) = float((x + y + t) % 256) / 255.0f;
        }
    return image;
}

// The 8-bit values an image holds.
std::vector<long> bytes(const Image& image) {
    std::vector<long> values;
    for (float v : image.pixels) values.push_back(std::lround(v * 255.0f));
    return values;
}

size_t filesIn(const std::string& folder) {
    size_t n = 0;
    for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(folder)) ++n;
    return n;
}

TEST(Video, LosslessRoundTripKeepsEveryFrameAndTheFrameRate) {
    testing::TempDir dir;
    const std::string path = dir.file("clip.mkv");
    {
        VideoWriter writer(path, 48, 32, 24.0);
        EXPECT_EQ(writer.codec(), "FFV1");
        for (int t = 0; t < 6; ++t) writer.write(movingEdge(48, 32, t));
        writer.close();
    }
    VideoReader reader(path);
    EXPECT_EQ(reader.info().width, 48);
    EXPECT_EQ(reader.info().height, 32);
    EXPECT_DOUBLE_EQ(reader.info().fps, 24.0);
    EXPECT_EQ(reader.info().codec, "FFV1");
    Image frame;
    int t = 0;
    for (; reader.read(frame); ++t) {
        ASSERT_LT(t, 6);
        EXPECT_EQ(frame.storage, PixelType::UInt8);
        EXPECT_EQ(bytes(frame), bytes(movingEdge(48, 32, t))) << "frame " << t;
    }
    EXPECT_EQ(t, 6);
}

// A linear-light image is encoded to sRGB on the way in; an H.264 file is lossy but close.
TEST(Video, LinearFramesAreEncodedAndH264IsClose) {
    testing::TempDir dir;
    Image linear = movingEdge(64, 48, 0);
    for (float& v : linear.pixels) v = srgbToLinear(v);
    linear.storage = PixelType::Float;
    VideoWriter writer(dir.file("clip.mp4"), 64, 48, 30.0);
    EXPECT_EQ(writer.codec(), "avc1");
    for (int t = 0; t < 3; ++t) writer.write(linear);
    writer.close();
    VideoReader reader(dir.file("clip.mp4"));
    Image frame;
    ASSERT_TRUE(reader.read(frame));
    const Image expected = movingEdge(64, 48, 0);
    double squared = 0;
    for (size_t i = 0; i < frame.pixels.size(); ++i)
        squared += std::pow(double(frame.pixels[i] - expected.pixels[i]), 2);
    const double psnr = 10 * std::log10(1.0 / (squared / double(frame.pixels.size())));
    EXPECT_GT(psnr, 25.0);
}

// An unclosed writer (an error on the way) leaves neither the video nor its temporary file, and an
// earlier file of that name is intact.
TEST(Video, AnUnclosedWriterLeavesNothing) {
    testing::TempDir dir;
    const std::string path = dir.file("clip.mkv");
    {
        VideoWriter writer(path, 48, 32, 24.0);
        writer.write(movingEdge(48, 32, 0));
    }
    EXPECT_EQ(filesIn(dir.path()), 0u);
    { std::ofstream(path) << "earlier"; }
    {
        VideoWriter writer(path, 48, 32, 24.0);
        writer.write(movingEdge(48, 32, 0));
        EXPECT_THROW(writer.write(movingEdge(40, 32, 0)), Error);
    }
    std::ifstream in(path);
    std::string text;
    in >> text;
    EXPECT_EQ(text, "earlier");
    EXPECT_EQ(filesIn(dir.path()), 1u);
}

TEST(Video, BadFilesAndCodecsAreOneError) {
    testing::TempDir dir;
    { std::ofstream(dir.file("bad.mp4")) << "not a video"; }
    const auto message = [](auto&& f) {
        try {
            f();
        } catch (const Error& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_NE(message([&] { VideoReader r(dir.file("bad.mp4")); }).find("not a video"), std::string::npos);
    EXPECT_NE(message([&] { VideoReader r(dir.file("missing.mp4")); }).find("missing.mp4"),
              std::string::npos);
    EXPECT_NE(message([&] { VideoWriter w(dir.file("o.mkv"), 8, 8, 24.0, "ZZZZ"); }).find("ZZZZ"),
              std::string::npos);
    EXPECT_NE(message([&] { VideoWriter w(dir.file("o.png"), 8, 8, 24.0); }).find("not a video"),
              std::string::npos);
    EXPECT_EQ(filesIn(dir.path()), 1u);
    EXPECT_TRUE(isVideoPath("a/B.MP4"));
    EXPECT_FALSE(isVideoPath("a/b.png"));
}

}  // namespace
}  // namespace dejag
