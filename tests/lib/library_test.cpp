// libdejag's public face (lib/include/dejag/dejag.h), linked as an engine links it: only the shared library
// and its header, none of dejag's internal headers.
#include <dejag/dejag.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

namespace {

std::vector<float> slantedEdge(int width, int height) {
    std::vector<float> frame(size_t(width) * height * 3);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            for (int c = 0; c < 3; ++c)
                frame[(size_t(y) * width + x) * 3 + c] = x * 3 > y * 5 + 10 ? 1.0f : 0.0f;
    return frame;
}

std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const dejag::api::Error& e) {
        return e.what();
    }
    return "no error";
}

TEST(Library, ListsTheMethodsWithTheirBuffers) {
    const std::vector<dejag::api::MethodInfo> methods = dejag::api::methods();
    const auto find = [&](const std::string& name) {
        return std::find_if(methods.begin(), methods.end(), [&](const auto& m) { return m.name == name; });
    };
    ASSERT_NE(find("fxaa"), methods.end());
    EXPECT_TRUE(find("fxaa")->needs.empty());
    ASSERT_NE(find("taa"), methods.end());
    EXPECT_TRUE(find("taa")->temporal);
    EXPECT_NE(std::find(find("taa")->needs.begin(), find("taa")->needs.end(), "motion"),
              find("taa")->needs.end());
    EXPECT_FALSE(dejag::api::version().empty());
}

TEST(Library, FiltersAFrameAndPassesTheIdentityThrough) {
    const int width = 64, height = 40;
    const std::vector<float> frame = slantedEdge(width, height);
    std::vector<float> out(frame.size());
    dejag::api::Filter none("none");
    none.setColour(frame.data(), width, height);
    none.execute(out.data());
    EXPECT_EQ(out, frame);
    for (const char* method : {"fxaa", "smaa", "cnn", "fxaa,cnn"}) {
        dejag::api::Filter filter(method);
        filter.setColour(frame.data(), width, height);
        filter.execute(out.data());
        double changed = 0;
        for (size_t i = 0; i < out.size(); ++i) {
            ASSERT_TRUE(out[i] >= 0.0f && out[i] <= 1.0f) << method;
            changed += std::abs(out[i] - frame[i]);
        }
        EXPECT_GT(changed, 1.0) << method;  // the edge is softened
        EXPECT_GE(filter.lastMilliseconds(), 0.0);
    }
}

TEST(Library, TemporalMethodsTakeTheirBuffers) {
    const int width = 48, height = 32;
    const std::vector<float> frame = slantedEdge(width, height);
    std::vector<float> depth(size_t(width) * height, 0.5f), motion(size_t(width) * height * 2, 0.0f),
        out(frame.size());
    dejag::api::Filter taa("taa");
    EXPECT_TRUE(taa.temporal());
    taa.setColour(frame.data(), width, height);
    EXPECT_NE(errorOf([&] { taa.execute(out.data()); }).find("depth"), std::string::npos);
    taa.setBuffer("depth", depth.data());
    taa.setBuffer("motion", motion.data());
    taa.setJitter(0.25f, -0.25f);
    for (int i = 0; i < 3; ++i) EXPECT_EQ(errorOf([&] { taa.execute(out.data()); }), "no error");
    taa.reset();
    EXPECT_EQ(errorOf([&] { taa.execute(out.data()); }), "no error");
}

TEST(Library, MistakesAreOneLineErrors) {
    EXPECT_NE(errorOf([] { dejag::api::Filter f("fxxa"); }).find("'fxxa' is not a method"),
              std::string::npos);
    EXPECT_NE(errorOf([] {
                  dejag::api::Filter f("fxaa", {{"presett", "12"}});
              }).find("presett"),
              std::string::npos);
    EXPECT_NE(errorOf([] {
                  dejag::api::Filter f("cnn", {{"model", "no-such-model"}});
              }).find("no-such-model"),
              std::string::npos);
    dejag::api::Filter filter("fxaa");
    EXPECT_NE(errorOf([&] { filter.setBuffer("normals", nullptr); }).find("'normals'"), std::string::npos);
    std::vector<float> out(12);
    EXPECT_NE(errorOf([&] { filter.execute(out.data()); }).find("no colour"), std::string::npos);
    EXPECT_NE(errorOf([&] { filter.setColour(out.data(), 2, 2, 2); }).find("3 channels"), std::string::npos);
}

}  // namespace
