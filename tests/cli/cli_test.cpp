// The `dejag` binary as a user meets it: outputs, exit codes, one-line errors, nothing half-written.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "base/simd.h"
#include "data/image.h"
#include "nn/model.h"
#include "tests/cli/cli_util.h"
#include "tests/test_util.h"

namespace dejag {
namespace {

std::string golden(const std::string& name) {
    return testing::sourcePath("tests/golden/metrics/" + name);
}

// The objects of a --json output, one a line.
std::vector<nlohmann::json> jsonLines(const std::string& out) {
    std::vector<nlohmann::json> objects;
    std::istringstream in(out);
    for (std::string line; std::getline(in, line);) objects.push_back(nlohmann::json::parse(line));
    return objects;
}

// A 40x30 8-bit RGB image of a slanted black and white edge.
Image slantedEdge() {
    Image edge(40, 30, {"R", "G", "B"}, PixelType::UInt8);
    for (int y = 0; y < 30; ++y)
        for (int x = 0; x < 40; ++x)
            for (int c = 0; c < 3; ++c) edge.at(x, y, c) = x * 3 > y * 4 ? 1.0f : 0.0f;
    return edge;
}

// --version: the version, the build (type and compiler) and every SIMD level this CPU can run, best first.
TEST(Cli, VersionNamesTheBuildAndTheCpusSimdLevels) {
    testing::TempDir dir;
    const RunResult r = run("--version", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(r.out.rfind("dejag 0.", 0), 0u) << r.out;
    EXPECT_NE(r.out.find("\nbuild: "), std::string::npos) << r.out;
    std::string levels;
    for (int level = int(cpuSimdLevel()); level >= 0; --level)
        levels += std::string(levels.empty() ? "" : ", ") + simdLevelName(SimdLevel(level));
    EXPECT_NE(r.out.find("SIMD on this CPU: " + levels), std::string::npos) << r.out;
}

// Every command's --help ends with an example and speaks in one voice: option texts start in lower case
// (an acronym or a placeholder such as WxH may stay in capitals).
TEST(Cli, EveryHelpHasAnExampleAndOneCapitalisation) {
    testing::TempDir dir;
    for (const char* command : {"",
                                "render",
                                "data",
                                "data generate",
                                "data verify",
                                "data stats",
                                "train",
                                "train export",
                                "filter",
                                "metrics",
                                "bench",
                                "bench render",
                                "bench filter",
                                "bench stability",
                                "bench taa",
                                "bench quality",
                                "bench reach",
                                "bench metrics",
                                "demo",
                                "completion",
                                "export",
                                "view"}) {
        SCOPED_TRACE(command);
        const RunResult r = run(std::string(command) + " --help", dir);
        ASSERT_EQ(r.exitCode, 0) << r.err;
        EXPECT_NE(r.out.find("\nExample: dejag "), std::string::npos) << r.out;
        std::istringstream lines(r.out);
        bool pending = false;  // an option line too long for its text, which then starts on the next line
        for (std::string line; std::getline(lines, line);) {
            // An option's line: two spaces, a dash, its names, and the text from column 31.
            std::string text;
            if (line.rfind("  -", 0) == 0) {
                pending = line.size() < 31 || line[29] != ' ';
                if (!pending) text = line.substr(30);
            } else if (pending) {
                pending = false;
                if (line.size() > 31 && line.find_first_not_of(' ') == 30) text = line.substr(30);
            }
            EXPECT_FALSE(text.size() > 1 && std::isupper(static_cast<unsigned char>(text[0])) &&
                         std::islower(static_cast<unsigned char>(text[1])))
                << line;
        }
    }
}

// `dejag completion bash` completes subcommands and each command's flags, nested ones too; any other shell
// is one error line.
TEST(Cli, BashCompletionCompletesCommandsAndTheirFlags) {
    testing::TempDir dir;
    const std::string script = dir.file("complete.sh");
    std::ofstream(script)
        << "source <('" << DEJAG_BINARY
        << "' completion bash) || exit 1\n"
           "t() { COMP_WORDS=(\"$@\"); COMP_CWORD=$((${#COMP_WORDS[@]} - 1)); _dejag; "
           "echo \"${COMPREPLY[*]}\"; }\n"
           "t dejag fil\nt dejag filter --me\nt dejag bench q\nt dejag bench filter --thread\n"
           "t dejag data generate --fam\nt dejag --thr\n";
    const std::string out = dir.file("out.txt");
    ASSERT_EQ(std::system(("bash '" + script + "' >'" + out + "'").c_str()), 0);
    EXPECT_EQ(slurp(out), "filter\n--method\nquality\n--thread-counts --threads\n--families\n\n");
    expectOneLineError(run("completion zsh", dir), "'zsh' is not a shell dejag completes");
}

// `cmake --install` (into a prefix of the test's own) puts the binary, the shipped models and their cards,
// the bash completion and the man page in place; the installed binary finds the models by name.
TEST(Cli, InstallPutsTheBinaryModelsCompletionAndManPage) {
    testing::TempDir dir;
    const std::string build = std::filesystem::path(DEJAG_BINARY).parent_path().string();  // the build tree
    const std::string prefix = dir.file("prefix");
    ASSERT_EQ(std::system(("cmake --install '" + build + "' --prefix '" + prefix + "' >/dev/null").c_str()),
              0);
    for (const char* file :
         {"bin/dejag", "share/dejag/models/dejag-fast.safetensors", "share/dejag/models/dejag-fast.md",
          "share/dejag/models/dejag-guided.safetensors", "share/bash-completion/completions/dejag",
          "share/man/man1/dejag.1"})
        EXPECT_TRUE(std::filesystem::is_regular_file(prefix + "/" + file)) << file;
    EXPECT_NE(slurp(prefix + "/share/man/man1/dejag.1").find("learns to remove aliasing"), std::string::npos);
    writeImage(dir.file("edge.png"), slantedEdge());
    const std::string command =
        "cd '" + dir.path().string() + "' && '" + prefix +
        "/bin/dejag' filter --method cnn --model dejag-guided --json edge.png out.png >'" +
        dir.file("run.json") + "'";
    ASSERT_EQ(std::system(command.c_str()), 0);
    EXPECT_NE(slurp(dir.file("run.json")).find(prefix + "/share/dejag/models/dejag-guided.safetensors"),
              std::string::npos)
        << slurp(dir.file("run.json"));
}

// The library an engine links: `cmake --install` puts libdejag, its header, a CMake package and a
// pkg-config file in place; the installed example builds against the package (find_package(dejag)) and
// against pkg-config, and runs FXAA, SMAA and the shipped network (found beside the installed library).
TEST(Cli, InstalledLibraryBuildsTheExampleWithCMakeAndPkgConfig) {
#if defined(DEJAG_SANITIZE_ADDRESS) || defined(DEJAG_SANITIZE_THREAD)
    GTEST_SKIP()
        << "an uninstrumented example cannot load a sanitizer-instrumented libdejag (the runtime must "
           "come first); Library.* test the face in this build";
#endif
    testing::TempDir dir;
    const std::string build = std::filesystem::path(DEJAG_BINARY).parent_path().string();
    const std::string prefix = dir.file("prefix");
    ASSERT_EQ(std::system(("cmake --install '" + build + "' --prefix '" + prefix + "' >/dev/null").c_str()),
              0);
    for (const char* file : {"lib/libdejag.so", "include/dejag/dejag.h", "lib/cmake/dejag/dejagConfig.cmake",
                             "lib/cmake/dejag/dejagTargets.cmake", "lib/pkgconfig/dejag.pc",
                             "share/dejag/examples/filter_frame.cpp", "share/dejag/examples/CMakeLists.txt"})
        EXPECT_TRUE(std::filesystem::exists(prefix + "/" + file)) << file;
    const std::string examples = prefix + "/share/dejag/examples";
    const std::string log = dir.file("build.log");
    const std::string cmake = "cmake -S '" + examples + "' -B '" + dir.file("example") +
                              "' -DCMAKE_PREFIX_PATH='" + prefix + "' >'" + log +
                              "' 2>&1 && cmake --build '" + dir.file("example") + "' >>'" + log + "' 2>&1";
    ASSERT_EQ(std::system(cmake.c_str()), 0) << slurp(log);
    const std::string out = dir.file("out.txt");
    // Run from elsewhere: the network is found beside the library, not in the working directory.
    ASSERT_EQ(std::system(("cd / && '" + dir.file("example/filter_frame") + "' >'" + out + "' 2>&1").c_str()),
              0)
        << slurp(out);
    const std::string text = slurp(out);
    for (const char* method : {"fxaa ", "smaa ", "cnn "}) {
        const size_t at = text.find(std::string("\n") + method);
        ASSERT_NE(at, std::string::npos) << text;
        const double changed = std::atof(text.c_str() + text.find("changed ", at) + 8);
        EXPECT_GT(changed, 1.0) << method << ": " << text;
    }
    const std::string pkg = "PKG_CONFIG_PATH='" + prefix + "/lib/pkgconfig' ";
    const std::string compile = "g++ -std=c++17 '" + examples + "/filter_frame.cpp' -o '" + dir.file("pc") +
                                "' $(" + pkg + "pkg-config --cflags --libs dejag) -Wl,-rpath,'" + prefix +
                                "/lib' >'" + log + "' 2>&1";
    ASSERT_EQ(std::system(compile.c_str()), 0) << slurp(log);
    ASSERT_EQ(std::system(("'" + dir.file("pc") + "' fxaa,cnn >'" + out + "' 2>&1").c_str()), 0)
        << slurp(out);
    EXPECT_NE(slurp(out).find("fxaa,cnn changed"), std::string::npos) << slurp(out);
    // An unknown method is the library's one-line error.
    EXPECT_NE(std::system(("'" + dir.file("pc") + "' fxxa >'" + out + "' 2>&1").c_str()), 0);
    EXPECT_NE(slurp(out).find("filter_frame: 'fxxa' is not a method"), std::string::npos) << slurp(out);
}

TEST(Cli, MetricsJsonHasTheDocumentedKeys) {
    testing::TempDir dir;
    const RunResult r =
        run("metrics --json " + golden("colour_ref.png") + " " + golden("colour_test.png"), dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    for (const char* key : {"mse", "rmse", "psnr", "snr", "ssim"}) EXPECT_TRUE(j[key].is_number()) << key;
    EXPECT_EQ(j["data_range"].get<double>(), 255.0);
    EXPECT_EQ(j["ssim_channels"].size(), 3u);
    EXPECT_FALSE(j["identical"].get<bool>());
}

// --aliasing on the receding textured planes: the samplers in the order of their known aliasing (point,
// bilinear, trilinear, anisotropic), each against one truth of 256 point samples; the anisotropic and the
// Fourier samplers keep more detail than the trilinear one, which blurs the receding planes, and the
// Fourier sampler aliases less than it. A sequence is refused.
TEST(Cli, MetricsAliasingOrdersTheTextureSamplers) {
    testing::TempDir dir;
    // The truth: the texture's own texels averaged over the pixel (point samples at 256 jittered places).
    RunResult r = run("render --scene planes --size 256x256 --sampler point --truth 256 --quiet --out '" +
                          dir.file("truth") + "'",
                      dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    double previous = INFINITY, trilinearKept = 0, trilinearAliasing = 0;
    for (const char* sampler : {"point", "bilinear", "trilinear", "aniso16", "fourier"}) {
        SCOPED_TRACE(sampler);
        r = run(std::string("render --scene planes --size 256x256 --quiet --sampler ") + sampler +
                    " --out '" + dir.file(sampler) + "'",
                dir);
        ASSERT_EQ(r.exitCode, 0) << r.err;
        r = run("metrics --aliasing --json '" + dir.file("truth/truth_0000.exr") + "' '" +
                    dir.file(std::string(sampler) + "/frame_0000.exr") + "'",
                dir);
        ASSERT_EQ(r.exitCode, 0) << r.err;
        const nlohmann::json j = nlohmann::json::parse(r.out);
        const double aliasing = j["aliasing"].get<double>(), kept = j["detail_kept"].get<double>();
        std::printf("%-10s aliasing %.4f (%.1f dB), detail kept %.3f\n", sampler, aliasing,
                    j["aliasing_db"].get<double>(), kept);
        if (std::string(sampler) == "fourier") {
            // Less aliasing than trilinear filtering, with more of the detail (docs/texture-aa.md).
            EXPECT_LT(aliasing, trilinearAliasing);
            EXPECT_GT(kept, trilinearKept);
            continue;
        }
        EXPECT_LT(aliasing, previous);
        previous = aliasing;
        if (std::string(sampler) == "trilinear") trilinearKept = kept, trilinearAliasing = aliasing;
        if (std::string(sampler) == "aniso16") {
            EXPECT_GT(kept, trilinearKept);
        }
    }
    expectOneLineError(run("metrics --aliasing '" + dir.file("truth/frame_%04d.exr") + "' '" +
                               dir.file("point/frame_%04d.exr") + "'",
                           dir),
                       "--aliasing");
}

TEST(Cli, IdenticalImagesPrintInfiniteJsonPsnr) {
    testing::TempDir dir;
    const RunResult r = run("metrics --json " + golden("noise_ref.png") + " " + golden("noise_ref.png"), dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_TRUE(j["psnr"].is_null()) << r.out;
    EXPECT_TRUE(j["snr"].is_null()) << r.out;
    EXPECT_TRUE(j["identical"].get<bool>());
    EXPECT_EQ(j["mse"].get<double>(), 0.0);
    const RunResult text = run("metrics " + golden("noise_ref.png") + " " + golden("noise_ref.png"), dir);
    EXPECT_NE(text.out.find("PSNR       inf"), std::string::npos) << text.out;
}

TEST(Cli, SsimMapAndMaskOptions) {
    testing::TempDir dir;
    Image mask(96, 72, {"Y"}, PixelType::UInt8);
    for (int y = 0; y < 72; ++y)
        for (int x = 0; x < 48; ++x) mask.at(x, y, 0) = 1.0f;
    writeImage(dir.file("mask.png"), mask);
    const RunResult r =
        run("metrics --json --mask " + dir.file("mask.png") + " --ssim-map " + dir.file("map.png") + " " +
                golden("edges_ref.png") + " " + golden("edges_test.png"),
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["pixels"].get<int>(), 48 * 72);
    const Image map = readImage(dir.file("map.png"));
    EXPECT_EQ(map.width, 96);
    EXPECT_EQ(map.height, 72);
}

TEST(Cli, MissingFileIsOneLineAndExitTwo) {
    testing::TempDir dir;
    expectOneLineError(run("metrics " + golden("edges_ref.png") + " " + dir.file("missing.png"), dir),
                       "missing.png");
}

TEST(Cli, DifferentSizesAreOneLineNamingBothFiles) {
    testing::TempDir dir;
    const RunResult r = run("metrics " + golden("edges_ref.png") + " " + golden("odd_size_test.png"), dir);
    expectOneLineError(r, "odd_size_test.png");
    EXPECT_NE(r.err.find("edges_ref.png"), std::string::npos);
}

TEST(Cli, DifferentChannelCountsAreAnError) {
    testing::TempDir dir;
    expectOneLineError(run("metrics " + golden("rgba_ref.png") + " " + golden("rgba_ref.png") + " --mask " +
                               golden("edges_ref.png"),
                           dir),
                       "mask");
    Image grey(96, 72, {"Y"}, PixelType::UInt8);
    writeImage(dir.file("grey.png"), grey);
    expectOneLineError(run("metrics " + golden("colour_ref.png") + " " + dir.file("grey.png"), dir),
                       "channels");
}

// Two sequences: every frame's figures and the flicker, computed here from the definition
// (docs/metrics.md); a test that flickers against a steady truth scores exactly its frame-to-frame change.
TEST(Cli, MetricsScoresSequencesFrameByFrameWithTheirFlicker) {
    testing::TempDir dir;
    namespace fs = std::filesystem;
    fs::create_directories(dir.file("ref")), fs::create_directories(dir.file("test"));
    const int W = 20, H = 16;
    for (int t = 0; t < 4; ++t) {
        Image truth(W, H, {"R", "G", "B"}, PixelType::Float), test = truth;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x)
                for (int c = 0; c < 3; ++c) {
                    truth.at(x, y, c) = float((x + y + c) % 5) / 5.0f;
                    // the test: the truth, with every other frame 0.1 brighter in its left half
                    test.at(x, y, c) = truth.at(x, y, c) + (t % 2 == 1 && x < W / 2 ? 0.1f : 0.0f);
                }
        char name[64];
        std::snprintf(name, sizeof name, "f_%04d.exr", t + 7);
        writeImage(dir.file("ref") + "/" + name, truth);
        writeImage(dir.file("test") + "/" + name, test);
    }
    const RunResult r = run("metrics --json " + dir.file("ref/f_%04d.exr") + " " + dir.file("test"), dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const std::vector<nlohmann::json> lines = jsonLines(r.out);
    ASSERT_EQ(lines.size(), 5u) << r.out;
    EXPECT_EQ(lines[0]["frame"].get<int>(), 7);
    EXPECT_TRUE(lines[0]["psnr"].is_null()) << "frame 7 is the truth itself";
    EXPECT_TRUE(lines[0]["flicker"].is_null());
    for (int t = 1; t < 4; ++t) EXPECT_NEAR(lines[size_t(t)]["flicker"].get<double>(), 0.05, 1e-6) << t;
    EXPECT_TRUE(lines[4]["summary"].get<bool>());
    EXPECT_NEAR(lines[4]["flicker"].get<double>(), 0.05, 1e-6);
    EXPECT_EQ(lines[4]["frames"].get<int>(), 4);
    // One sequence against one image, or frames the reference lacks: one line each.
    const RunResult mixed = run("metrics " + dir.file("ref") + " " + dir.file("ref/f_0007.exr"), dir);
    EXPECT_EQ(mixed.exitCode, 2);
    EXPECT_NE(mixed.err.find("is a sequence and"), std::string::npos) << mixed.err;
    fs::copy_file(dir.file("test/f_0010.exr"), dir.file("test/f_0011.exr"));
    const RunResult missing = run("metrics " + dir.file("ref") + " " + dir.file("test"), dir);
    EXPECT_EQ(missing.exitCode, 2);
    EXPECT_NE(missing.err.find("does not hold"), std::string::npos) << missing.err;
}

TEST(Cli, MetricsScoresADatasetInputOnTheColourChannelsItSharesWithTheTruth) {
    testing::TempDir dir;
    Image truth(24, 20, {"R", "G", "B"}, PixelType::Float);
    Image input(24, 20, {"R", "G", "B", "albedo.R", "albedo.G", "albedo.B", "depth.Z"}, PixelType::Float);
    Image colour(24, 20, {"R", "G", "B"}, PixelType::Float);
    for (int y = 0; y < 20; ++y)
        for (int x = 0; x < 24; ++x)
            for (int c = 0; c < 3; ++c) {
                truth.at(x, y, c) = float((x * 7 + y * 3 + c) % 11) / 10.0f;
                colour.at(x, y, c) = input.at(x, y, c) = float((x * 5 + y * 3 + c) % 13) / 12.0f;
                input.at(x, y, 3 + c) = 0.5f;
                input.at(x, y, 6) = 100.0f + float(x);  // far from the colours: would ruin the score if used
            }
    writeImage(dir.file("truth.exr"), truth);
    writeImage(dir.file("input.exr"), input);
    writeImage(dir.file("colour.exr"), colour);
    const RunResult matched =
        run("metrics --json " + dir.file("truth.exr") + " " + dir.file("input.exr"), dir);
    const RunResult plain =
        run("metrics --json " + dir.file("truth.exr") + " " + dir.file("colour.exr"), dir);
    ASSERT_EQ(matched.exitCode, 0) << matched.err;
    ASSERT_EQ(plain.exitCode, 0) << plain.err;
    const auto a = nlohmann::json::parse(matched.out), b = nlohmann::json::parse(plain.out);
    EXPECT_TRUE(a["matched_by_name"].get<bool>());
    EXPECT_FALSE(b["matched_by_name"].get<bool>());
    EXPECT_EQ(a["psnr"].get<double>(), b["psnr"].get<double>());
    EXPECT_EQ(a["ssim"].get<double>(), b["ssim"].get<double>());
    // Either order: the truth as the test image is matched against the input's colour.
    const RunResult swapped =
        run("metrics --json " + dir.file("input.exr") + " " + dir.file("truth.exr"), dir);
    ASSERT_EQ(swapped.exitCode, 0) << swapped.err;
    EXPECT_EQ(nlohmann::json::parse(swapped.out)["mse"].get<double>(), a["mse"].get<double>());
    const RunResult text = run("metrics " + dir.file("truth.exr") + " " + dir.file("input.exr"), dir);
    EXPECT_NE(text.out.find("matched by name"), std::string::npos) << text.out;
    // Filtered, a dataset input keeps its buffers in an EXR and writes its colour alone to a PNG.
    for (const char* name : {"f.exr", "f.png"})
        ASSERT_EQ(run("filter --method fxaa " + dir.file("input.exr") + " " + dir.file(name), dir).exitCode,
                  0);
    EXPECT_EQ(readImage(dir.file("f.exr")).channels(), 7);
    EXPECT_EQ(readImage(dir.file("f.png")).channelNames, (std::vector<std::string>{"R", "G", "B"}));
    // Channels neither image holds all of: still one error line naming both sets.
    Image other(24, 20, {"R", "G", "depth.Z", "id"}, PixelType::Float);
    writeImage(dir.file("other.exr"), other);
    expectOneLineError(run("metrics " + dir.file("truth.exr") + " " + dir.file("other.exr"), dir),
                       "neither holds all");
}

TEST(Cli, TruncatedFileIsOneLineAndWritesNothing) {
    testing::TempDir dir;
    const auto size = std::filesystem::file_size(golden("noise_ref.png"));
    std::filesystem::copy_file(golden("noise_ref.png"), dir.file("cut.png"));
    std::filesystem::resize_file(dir.file("cut.png"), size / 3);
    expectOneLineError(run("metrics --ssim-map " + dir.file("map.png") + " " + golden("noise_ref.png") + " " +
                               dir.file("cut.png"),
                           dir),
                       "cut.png");
    EXPECT_FALSE(std::filesystem::exists(dir.file("map.png")));
    EXPECT_EQ(filesIn(dir.path()), 1u);
}

TEST(Cli, UnwritableMapFolderIsAnErrorAndLeavesNothing) {
    testing::TempDir dir;
    expectOneLineError(run("metrics --ssim-map " + dir.file("no/such/map.png") + " " +
                               golden("edges_ref.png") + " " + golden("edges_test.png"),
                           dir),
                       "no/such");
    EXPECT_EQ(filesIn(dir.path()), 0u);
}

TEST(Cli, NanInAFloatImageIsReported) {
    testing::TempDir dir;
    Image image(16, 16, {"R", "G", "B"}, PixelType::Float);
    image.at(3, 4, 1) = std::nanf("");
    writeImage(dir.file("nan.exr"), image);
    Image clean(16, 16, {"R", "G", "B"}, PixelType::Float);
    writeImage(dir.file("clean.exr"), clean);
    const RunResult r = run("metrics " + dir.file("clean.exr") + " " + dir.file("nan.exr"), dir);
    expectOneLineError(r, "nan.exr");
    EXPECT_NE(r.err.find("(3, 4)"), std::string::npos) << r.err;
}

TEST(Cli, UnknownFlagAndMissingArgumentsAreOneLine) {
    testing::TempDir dir;
    expectOneLineError(
        run("metrics --bogus " + golden("edges_ref.png") + " " + golden("edges_test.png"), dir), "--bogus");
    expectOneLineError(run("metrics " + golden("edges_ref.png"), dir), "TEST");
    expectOneLineError(run("frobnicate", dir), "frobnicate");
    expectOneLineError(run("", dir), "subcommand");
    expectOneLineError(
        run("metrics --data-range -3 " + golden("edges_ref.png") + " " + golden("edges_test.png"), dir),
        "data-range");
}

TEST(Cli, BadSimdEnvironmentIsOneLine) {
    testing::TempDir dir;
    expectOneLineError(
        run("metrics " + golden("edges_ref.png") + " " + golden("edges_test.png"), dir, "DEJAG_SIMD=sse9"),
        "DEJAG_SIMD");
}

TEST(Cli, HelpExitsZeroAndDocumentsTheScale) {
    testing::TempDir dir;
    const RunResult top = run("--help", dir);
    EXPECT_EQ(top.exitCode, 0);
    EXPECT_NE(top.out.find("metrics"), std::string::npos);
    const RunResult metrics = run("metrics --help", dir);
    EXPECT_EQ(metrics.exitCode, 0);
    EXPECT_NE(metrics.out.find("0-255"), std::string::npos) << metrics.out;
    EXPECT_NE(metrics.out.find("--json"), std::string::npos);
}

TEST(Cli, BenchMetricsRunsSmallAndPrintsJson) {
    testing::TempDir dir;
    const RunResult r = run("bench metrics --size 64x48 --repeat 1 --threads 1 --json", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    int rows = 0;
    for (const nlohmann::json& j : jsonLines(r.out)) {
        EXPECT_GT(j["ms"].get<double>(), 0.0);
        EXPECT_GT(j["peak_gmacs"].get<double>(), 0.0);
        ++rows;
    }
    EXPECT_EQ(rows, 2);
    // A sweep is --thread-counts; --threads is one count, as in every other command.
    const RunResult sweep = run("bench metrics --size 64x48 --repeat 1 --thread-counts 1,2 --json", dir);
    ASSERT_EQ(sweep.exitCode, 0) << sweep.err;
    EXPECT_EQ(jsonLines(sweep.out).size(), 4u);
    EXPECT_EQ(jsonLines(sweep.out).back()["threads"], 2);
    expectOneLineError(run("bench metrics --threads 1 --thread-counts 1,2", dir), "not both");
    expectOneLineError(run("bench metrics --threads 1,2", dir), "--threads");
    expectOneLineError(run("bench metrics --thread-counts 1,x", dir), "--thread-counts '1,x'");
}

TEST(Cli, BenchNnRunsTheKernelBenchmarkWithPeers) {
    testing::TempDir dir;
    const RunResult r = run("bench nn --case conv1x1 --repeat 1 --threads 1 --json", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["threads"].get<int>(), 1);
    EXPECT_GT(j["ms"].get<double>(), 0.0);
    EXPECT_GT(j["peak_fraction"].get<double>(), 0.0);
    // Peers are optional (installed by make bench): a number when present, null otherwise.
    for (const char* key : {"onednn_ratio", "libtorch_ratio"})
        EXPECT_TRUE(j[key].is_number() || j[key].is_null()) << key;
    expectOneLineError(run("bench nn --bogus", dir), "--bogus");
}

TEST(Cli, RenderWritesBuffersPreviewsTruthAndSidecar) {
    testing::TempDir dir;
    const std::string out = dir.file("pipe");
    const RunResult r =
        run("render --scene pipe --size 64x48 --frames 2 --jitter halton16 --truth 8 "
            "--buffers color,depth,motion,id --out '" +
                out + "' --json",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const nlohmann::json printed = nlohmann::json::parse(r.out);
    const nlohmann::json sidecar = nlohmann::json::parse(slurp(out + "/render.json"));
    EXPECT_EQ(printed, sidecar);
    EXPECT_EQ(sidecar["frames"].size(), 2u);
    EXPECT_EQ(sidecar["truth"]["samples"].get<int>(), 8);
    EXPECT_EQ(sidecar["frames"][1]["truth"]["samples"].get<int>(), 8);
    for (const char* name :
         {"frame_0000.exr", "frame_0000.png", "frame_0001.exr", "truth_0001.exr", "truth_0001.png"})
        EXPECT_TRUE(std::filesystem::exists(out + "/" + name)) << name;
    const Image frame = readImage(out + "/frame_0001.exr");
    // OpenEXR orders channels by layer; readers find them by name.
    std::set<std::string> channels(frame.channelNames.begin(), frame.channelNames.end());
    EXPECT_EQ(channels, (std::set<std::string>{"R", "G", "B", "depth.Z", "motion.X", "motion.Y", "id.ID"}));
    EXPECT_EQ(frame.width, 64);
    EXPECT_EQ(frame.storage, PixelType::Float);
    const Image preview = readImage(out + "/frame_0001.png");
    EXPECT_EQ(preview.storage, PixelType::UInt8);
    // The jitter of frame 1 is Halton point 1 times the spread: x = 0.5 -> 0, y = 2/3 -> 1.7/6 up.
    EXPECT_NEAR(sidecar["frames"][1]["jitter_pixels"][0].get<double>(), 0.0, 1e-12);
    EXPECT_NEAR(sidecar["frames"][1]["jitter_pixels"][1].get<double>(), -1.7 / 6, 1e-9);

    // Another render into the folder is refused (one line, nothing touched); --force replaces the earlier
    // render: its frames go, so no scene mixes with another.
    const std::string before = slurp(out + "/frame_0001.exr");
    expectOneLineError(run("render --scene atrium --size 64x48 --out '" + out + "'", dir),
                       "already holds a render of pipe, 2 frame(s)");
    EXPECT_EQ(slurp(out + "/frame_0001.exr"), before);
    ASSERT_EQ(run("render --scene atrium --size 64x48 --quiet --force --out '" + out + "'", dir).exitCode, 0);
    EXPECT_EQ(nlohmann::json::parse(slurp(out + "/render.json"))["scene"], "atrium");
    for (const char* name : {"frame_0001.exr", "frame_0001.png", "truth_0001.exr", "truth_0000.png"})
        EXPECT_FALSE(std::filesystem::exists(out + "/" + name)) << name;
    EXPECT_TRUE(std::filesystem::exists(out + "/frame_0000.exr"));
    // A frame file without a render.json beside it is refused too.
    const std::string loose = dir.file("loose");
    std::filesystem::create_directories(loose);
    std::filesystem::copy_file(out + "/frame_0000.exr", loose + "/frame_0000.exr");
    expectOneLineError(run("render --scene pipe --size 64x48 --out '" + loose + "'", dir),
                       "already holds 'frame_0000.exr'");
}

// "-": one image through standard input and output, in the input's format (told by its first bytes);
// the bytes equal a run between files. Empty or foreign input, --json with "-" out, two "-" in metrics:
// one line each.
TEST(Cli, FilterAndMetricsTakeOneImageOnStandardStreams) {
    testing::TempDir dir;
    const Image edge = slantedEdge();
    writeImage(dir.file("edge.png"), edge);
    ASSERT_EQ(
        run("filter --method fxaa --quiet '" + dir.file("edge.png") + "' '" + dir.file("file.png") + "'", dir)
            .exitCode,
        0);
    RunResult r = run("filter --method fxaa --quiet - - <'" + dir.file("edge.png") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(r.out, slurp(dir.file("file.png")));
    // An EXR in gives an EXR out.
    writeImage(dir.file("edge.exr"), edge);
    r = run("filter --method fxaa --quiet - - <'" + dir.file("edge.exr") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(r.out.compare(0, 4, std::string("\x76\x2f\x31\x01", 4)), 0);
    r = run("metrics --json '" + dir.file("edge.png") + "' - <'" + dir.file("file.png") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const nlohmann::json scored = nlohmann::json::parse(r.out);
    EXPECT_EQ(scored["test"], "-");
    r = run("metrics --json '" + dir.file("edge.png") + "' '" + dir.file("file.png") + "'", dir);
    EXPECT_EQ(nlohmann::json::parse(r.out)["psnr"], scored["psnr"]);
    expectOneLineError(run("filter --method fxaa - '" + dir.file("x.png") + "' </dev/null", dir), "is empty");
    expectOneLineError(
        run("filter --method fxaa - '" + dir.file("x.png") + "' <'" + dir.file("edge.png") + ".no'", dir,
            "echo text >'" + dir.file("edge.png") + ".no';"),
        "not a PNG, JPEG, TIFF or OpenEXR image");
    expectOneLineError(run("filter --method fxaa --json '" + dir.file("edge.png") + "' -", dir), "--json");
    expectOneLineError(run("metrics - - <'" + dir.file("edge.png") + "'", dir), "both be '-'");
}

// Videos: a folder of frames into a lossless video at --fps, the video filtered into a video and into
// frames, each identical to filtering the frames themselves; metrics frame by frame with a video on either
// side; a temporal method, a foreign codec, an existing output and a corrupt file are one line each.
TEST(Cli, FilterAndMetricsTakeVideos) {
    testing::TempDir dir;
    std::filesystem::create_directories(dir.file("in"));
    for (int t = 0; t < 4; ++t) {
        Image frame = slantedEdge();
        for (int y = 0; y < frame.height; ++y)
            for (int x = 0; x < frame.width; ++x) frame.at(x, y, 1) = (x - t) * 3 > y * 4 ? 1.0f : 0.0f;
        writeImage(dir.file("in/f_000" + std::to_string(t) + ".png"), frame);
    }
    const std::string here = "cd '" + dir.path().string() + "' && ";
    const auto ok = [&](const std::string& arguments) {
        const RunResult r = run(arguments, dir, here);
        EXPECT_EQ(r.exitCode, 0) << arguments << "\n" << r.err;
        return r;
    };
    ok("filter --method none --quiet --fps 24 in clip.mkv");
    RunResult r = ok("filter --method fxaa --json clip.mkv out.mkv");
    nlohmann::json summary = nlohmann::json::parse(r.out);
    EXPECT_EQ(summary["frames"], 4);
    EXPECT_EQ(summary["fps"], 24.0);
    EXPECT_EQ(summary["codec"], "FFV1");
    EXPECT_EQ(summary["width"], 40);
    ok("filter --method fxaa --quiet clip.mkv frames/");
    ok("filter --method fxaa --quiet 'in/f_%04d.png' 'direct/f_%04d.png'");
    for (const char* test : {"out.mkv", "frames"}) {
        r = ok(std::string("metrics --json 'direct/f_%04d.png' ") + test);
        const std::vector<nlohmann::json> rows = jsonLines(r.out);
        ASSERT_EQ(rows.size(), 5u) << test;
        for (size_t i = 0; i < 4; ++i) EXPECT_TRUE(rows[i]["psnr"].is_null()) << test << " frame " << i;
    }
    // Scored against the unfiltered video: every frame differs, the rows say so.
    r = ok("metrics clip.mkv out.mkv");
    EXPECT_NE(r.out.find("4 frames: PSNR mean"), std::string::npos) << r.out;
    expectOneLineError(run("filter --method taa clip.mkv t.mkv", dir, here), "depth and motion");
    expectOneLineError(run("filter --method fxaa --codec QQQQ clip.mkv q.mkv", dir, here), "'QQQQ'");
    expectOneLineError(run("filter --method fxaa clip.mkv out.mkv", dir, here), "add --force");
    expectOneLineError(run("filter --method fxaa --codec FFV1 clip.mkv x.png", dir, here), "--codec");
    expectOneLineError(run("filter --method fxaa bad.mp4 b.mkv", dir, here + "echo text > bad.mp4;"),
                       "not a video");
    expectOneLineError(run("metrics clip.mkv 'in/f_%04d.png' --json", dir, here + "rm in/f_0003.png;"),
                       "ends after 3");
    EXPECT_FALSE(std::filesystem::exists(dir.file("q.mkv")));
    EXPECT_FALSE(std::filesystem::exists(dir.file("b.mkv")));
}

// dejag export --onnx: a shipped model by name into a file (checked against OpenCV's DNN module by
// Onnx.*), the recurrent one too; an existing file without --force, a missing folder and a size the
// network cannot take are one line each, and nothing is written. --glsl likewise into a folder.
TEST(Cli, ExportWritesOnnxAndRefusesWhatItCannot) {
    testing::TempDir dir;
    RunResult r = run("export --onnx --json dejag-fast '" + dir.file("fast.onnx") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const nlohmann::json summary = nlohmann::json::parse(r.out);
    EXPECT_EQ(summary["opset"], 13);
    EXPECT_EQ(summary["input_channels"], 3);
    EXPECT_EQ(summary["size"], "symbolic");
    const std::string bytes = slurp(dir.file("fast.onnx"));
    EXPECT_EQ(size_t(summary["bytes"]), bytes.size());
    EXPECT_NE(bytes.find("dejag.architecture"), std::string::npos);
    expectOneLineError(run("export --onnx dejag-fast '" + dir.file("fast.onnx") + "'", dir), "--force");
    r = run("export --onnx --force --size 64x48 dejag-guided '" + dir.file("fast.onnx") + "'", dir);
    EXPECT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("1x6x48x64"), std::string::npos) << r.out;
    expectOneLineError(run("export --onnx dejag-fast '" + dir.file("no/such/folder/x.onnx") + "'", dir),
                       "does not exist");
    // The recurrent network too (its values checked by Onnx.RecurrentExportsMatchTheGoldenEvaluation).
    r = run("export --onnx --json dejag-temporal '" + dir.file("t.onnx") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(nlohmann::json::parse(r.out)["input_channels"], 16);
    EXPECT_NE(slurp(dir.file("t.onnx")).find("GatherElements"), std::string::npos);
    expectOneLineError(run("export --onnx --size 30x20 dejag-fast '" + dir.file("s.onnx") + "'", dir), "30");
    expectOneLineError(run("export dejag-fast '" + dir.file("n.onnx") + "'", dir), "--onnx or --glsl");
    EXPECT_EQ(filesIn(dir.path()), 2u);
    // --glsl: a folder of passes (run against the CPU by Glsl.*), replaced only when it holds an export.
    r = run("export --glsl --json dejag-fast '" + dir.file("glsl") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(nlohmann::json::parse(r.out)["passes"], 16);
    EXPECT_EQ(filesIn(dir.file("glsl")), 18u);  // 16 passes, weights.bin, network.json
    expectOneLineError(run("export --glsl dejag-fast '" + dir.file("glsl") + "'", dir), "--force");
    r = run("export --glsl --force dejag-guided '" + dir.file("glsl") + "'", dir);
    EXPECT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(filesIn(dir.file("glsl")), 20u);  // the guided network's 18 passes, none of the old left
    std::filesystem::create_directories(dir.file("other"));
    std::ofstream(dir.file("other/notes.txt")) << "mine";
    expectOneLineError(run("export --glsl --force dejag-fast '" + dir.file("other") + "'", dir),
                       "no GLSL export");
    expectOneLineError(run("export --glsl --size 64x48 dejag-fast '" + dir.file("g2") + "'", dir), "--size");
    // The recurrent network too: its warps and accumulate are passes (run against the CPU by Glsl.*).
    r = run("export --glsl dejag-temporal '" + dir.file("g3") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(slurp(dir.file("g3/network.json")).find("\"accumulate\""), std::string::npos);
    r = run("export --glsl fxaa '" + dir.file("fxaa") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(slurp(dir.file("fxaa/fxaa.comp")).find("#version 430"), std::string::npos);
    EXPECT_TRUE(std::filesystem::exists(dir.file("fxaa/network.json")));
    // The other methods, with their settings: passes, tables and the description.
    r = run("export --glsl smaa --set preset=high '" + dir.file("smaa") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(filesIn(dir.file("smaa")), 6u);  // 3 passes, 2 tables, network.json
    EXPECT_EQ(std::filesystem::file_size(dir.file("smaa/orthogonal_areas.bin")),
              size_t(16 * 33 * 33 * 2 * 4));
    r = run("export --glsl taa-sobel '" + dir.file("tsobel") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(filesIn(dir.file("tsobel")), 6u);
    expectOneLineError(run("export --glsl taa --set motion-blur=true '" + dir.file("t2") + "'", dir),
                       "motion blur");
    expectOneLineError(run("export --glsl fxaa --set gate=off '" + dir.file("t3") + "'", dir), "gate");
    expectOneLineError(run("export --glsl --set subpix=1 dejag-fast '" + dir.file("t4") + "'", dir), "--set");
}

// The filter overwrites nothing unless asked: an existing output, of one image or any frame of a sequence,
// is one error line before any work, the file untouched; --force overwrites.
TEST(Cli, FilterRefusesToOverwriteWithoutForce) {
    testing::TempDir dir;
    const Image edge = slantedEdge();
    std::filesystem::create_directories(dir.file("in"));
    for (const char* name : {"edge.png", "in/f_0001.png", "in/f_0002.png", "in/f_0003.png"})
        writeImage(dir.file(name), edge);
    writeImage(dir.file("out.png"), edge);
    const std::string kept = slurp(dir.file("out.png"));
    auto fxaa = [&](const std::string& arguments) {
        return run("filter --method fxaa --quiet " + arguments, dir);
    };
    const std::string input = "'" + dir.file("edge.png") + "' ";
    expectOneLineError(fxaa(input + "'" + dir.file("out.png") + "'"),
                       "out.png' exists; add --force to overwrite");
    EXPECT_EQ(slurp(dir.file("out.png")), kept);
    ASSERT_EQ(fxaa("--force " + input + "'" + dir.file("out.png") + "'").exitCode, 0);
    EXPECT_NE(slurp(dir.file("out.png")), kept);
    // --out names the output as in every other command; the positional and --out together are refused.
    ASSERT_EQ(fxaa(input + "--out '" + dir.file("named.png") + "'").exitCode, 0);
    EXPECT_EQ(slurp(dir.file("named.png")), slurp(dir.file("out.png")));
    expectOneLineError(fxaa(input + "'" + dir.file("a.png") + "' --out '" + dir.file("b.png") + "'"),
                       "not both");
    // A sequence: the second and third frames' outputs exist; the first is not written either.
    std::filesystem::create_directories(dir.file("out"));
    writeImage(dir.file("out/g_0002.png"), edge);
    writeImage(dir.file("out/g_0003.png"), edge);
    expectOneLineError(
        run("filter --method fxaa '" + dir.file("in/f_%04d.png") + "' '" + dir.file("out/g_%04d.png") + "'",
            dir),
        "g_0002.png' exists (and 1 more of the outputs)");
    EXPECT_FALSE(std::filesystem::exists(dir.file("out/g_0001.png")));
}

TEST(Cli, RenderBadInputIsOneLineAndWritesNothing) {
    testing::TempDir dir;
    const std::string out = dir.file("out");
    expectOneLineError(run("render --scene teapot --out '" + out + "'", dir), "teapot");
    expectOneLineError(run("render --scene pipe --size 0x10 --out '" + out + "'", dir), "--size");
    expectOneLineError(run("render --scene pipe --size 20000x10 --out '" + out + "'", dir), "--size");
    expectOneLineError(run("render --scene pipe --frames 0 --out '" + out + "'", dir), "--frames");
    expectOneLineError(run("render --scene pipe --buffers color,normals --out '" + out + "'", dir),
                       "normals");
    expectOneLineError(run("render --scene pipe --jitter random --out '" + out + "'", dir), "--jitter");
    EXPECT_FALSE(std::filesystem::exists(out));
    std::ofstream(dir.file("a-file")) << "x";
    expectOneLineError(run("render --scene pipe --size 32x32 --out '" + dir.file("a-file") + "/sub'", dir),
                       "output folder");
}

TEST(Cli, BenchRenderQuickPrintsFramesAndTruth) {
    testing::TempDir dir;
    const RunResult r = run("bench render --quick --repeat 1 --json", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    int frames = 0, truths = 0;
    std::map<std::string, double> aliasing;  // the samplers' (their order: Cli.MetricsAliasing...)
    for (const nlohmann::json& j : jsonLines(r.out)) {
        EXPECT_GT(j["ms"].get<double>(), 0.0);
        if (j.contains("tile_samples_saving")) {
            ++truths;
            EXPECT_GE(j["tile_samples_saving"].get<double>(), 1.0);
        } else if (j.contains("aliasing")) {
            aliasing[j["name"].get<std::string>()] = j["aliasing"].get<double>();
            EXPECT_GT(j["detail_kept"].get<double>(), 0.0);
        } else {
            ++frames;
        }
    }
    EXPECT_EQ(frames, 2);
    EXPECT_EQ(truths, 1);
    ASSERT_EQ(aliasing.size(), 9u) << r.out;  // five samplers, Fourier with one probe, three normal maps
    EXPECT_EQ(aliasing.count("bump super"), 1u);
    EXPECT_GT(aliasing["sampler point"], 10 * aliasing["sampler trilinear"]);
}

// bench texture on a small frame: every family of tools on both kinds of scene, the Pareto front marked
// (the cheapest row is always on it), PNG plots and the JSON; an unknown case or bump mode is one line.
TEST(Cli, BenchTextureComparesEveryToolWithItsParetoFront) {
    testing::TempDir dir;
    const RunResult r = run("bench texture --quick --json --out '" + dir.file("texture") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::map<std::string, int> families;
    std::map<std::string, std::pair<double, bool>> cheapest;  // per case: ms, on the front
    int rows = 0;
    for (const nlohmann::json& j : jsonLines(r.out)) {
        ++rows;
        ++families[j["case"].get<std::string>() + " " + j["family"].get<std::string>()];
        EXPECT_GT(j["ms"].get<double>(), 0.0);
        EXPECT_TRUE(std::isfinite(j["psnr"].get<double>()));
        auto& c = cheapest.try_emplace(j["case"].get<std::string>(), INFINITY, false).first->second;
        if (j["ms"].get<double>() < c.first) c = {j["ms"].get<double>(), j["pareto"].get<bool>()};
    }
    EXPECT_EQ(rows, 13 + 11);
    EXPECT_EQ(families["checker source"], 5);  // the five samplers
    EXPECT_EQ(families["normal-map source"], 3);
    EXPECT_EQ(families["checker post-process"], 2);
    EXPECT_EQ(families["checker temporal"], 6);  // three TAAs on default and on point-sampled frames
    for (const auto& [name, c] : cheapest) EXPECT_TRUE(c.second) << name;
    EXPECT_TRUE(std::filesystem::exists(dir.file("texture/pareto-checker.png")));
    EXPECT_TRUE(std::filesystem::exists(dir.file("texture/pareto-normal-map.png")));
    EXPECT_TRUE(std::filesystem::exists(dir.file("texture/frequency-test.png")));
    EXPECT_EQ(nlohmann::json::parse(slurp(dir.file("texture/results.json"))).size(), size_t(rows));
    expectOneLineError(run("bench texture --quick --cases marble", dir), "marble");
    expectOneLineError(run("render --scene normal-map --bump shiny --out '" + dir.file("r") + "'", dir),
                       "shiny");
    expectOneLineError(run("render --scene planes --bump super --out '" + dir.file("r") + "'", dir),
                       "no normal map");
    expectOneLineError(
        run("render --scene normal-map --bump standard --bump-lobes 2 --out '" + dir.file("r") + "'", dir),
        "--bump super");
    expectOneLineError(run("render --scene planes --fourier-sigma 0.5 --out '" + dir.file("r") + "'", dir),
                       "--sampler fourier");
    expectOneLineError(
        run("render --scene planes --sampler fourier --fourier-probes 3 --out '" + dir.file("r") + "'", dir),
        "--fourier-probes");
    EXPECT_FALSE(std::filesystem::exists(dir.file("r")));
}

TEST(Cli, FilterFxaaKeepsBitDepthAndAlphaAndRefusesWhatItCannotDo) {
    testing::TempDir dir;
    // An aliased diagonal edge with an alpha channel, 8-bit PNG.
    Image edge(48, 40, {"R", "G", "B", "A"}, PixelType::UInt8);
    for (int y = 0; y < 40; ++y)
        for (int x = 0; x < 48; ++x) {
            const float v = y > 0.4 * x + 9 ? 1.0f : 0.0f;
            for (int c = 0; c < 3; ++c) edge.at(x, y, c) = v;
            edge.at(x, y, 3) = float((x + y) % 5) / 4.0f;
        }
    writeImage(dir.file("edge.png"), edge);
    const RunResult r = run("filter --method fxaa --preset 23 '" + dir.file("edge.png") + "' '" +
                                dir.file("out.png") + "' --json",
                            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_GT(j["processed_fraction"].get<double>(), 0.0);
    const Image out = readImage(dir.file("out.png"));
    edge = readImage(dir.file("edge.png"));  // as quantised to 8 bits
    EXPECT_EQ(out.storage, PixelType::UInt8);
    EXPECT_EQ(out.channels(), 4);
    bool changed = false;
    for (int y = 0; y < 40; ++y)
        for (int x = 0; x < 48; ++x) {
            ASSERT_EQ(out.at(x, y, 3), edge.at(x, y, 3));
            changed = changed || out.at(x, y, 0) != edge.at(x, y, 0);
        }
    EXPECT_TRUE(changed);
    expectOneLineError(run("filter --method cnn --model '" + dir.file("none.safetensors") + "' '" +
                               dir.file("edge.png") + "' '" + dir.file("t.png") + "'",
                           dir),
                       "none.safetensors");
    std::ofstream(dir.file("bad.safetensors")) << "not a model";
    expectOneLineError(run("filter --method cnn --model '" + dir.file("bad.safetensors") + "' '" +
                               dir.file("edge.png") + "' '" + dir.file("t.png") + "'",
                           dir),
                       "bad.safetensors");
    expectOneLineError(
        run("filter --method blur '" + dir.file("edge.png") + "' '" + dir.file("t.png") + "'", dir), "blur");
    expectOneLineError(
        run("filter --method taa '" + dir.file("edge.png") + "' '" + dir.file("t.png") + "'", dir),
        "no channel depth.Z");
    expectOneLineError(
        run("filter --method fxaa --preset 7 '" + dir.file("edge.png") + "' '" + dir.file("t.png") + "'",
            dir),
        "preset");
    expectOneLineError(
        run("filter --method fxaa '" + dir.file("missing.png") + "' '" + dir.file("t.png") + "'", dir),
        "missing.png");
    EXPECT_FALSE(std::filesystem::exists(dir.file("t.png")));
}

// The default --model (models/dejag-fast.safetensors, relative) is found from the binary when the
// working directory has no models/ folder.
TEST(Cli, FilterCnnFindsTheShippedModelFromAnyDirectory) {
    testing::TempDir dir;
    Image edge(40, 32, {"R", "G", "B"}, PixelType::UInt8);
    for (int y = 0; y < 32; ++y)
        for (int x = 0; x < 40; ++x)
            for (int c = 0; c < 3; ++c) edge.at(x, y, c) = y > 0.4 * x + 7 ? 1.0f : 0.0f;
    writeImage(dir.file("edge.png"), edge);
    ASSERT_FALSE(std::filesystem::exists(dir.path() / "models"));
    const RunResult r =
        run("filter --method cnn --json edge.png out.png", dir, "cd '" + dir.path().string() + "' &&");
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(nlohmann::json::parse(r.out)["model"].get<std::string>().find("dejag-fast.safetensors"),
              std::string::npos);
    EXPECT_EQ(readImage(dir.file("out.png")).width, 40);
    EXPECT_EQ(nlohmann::json::parse(r.out)["precision"], bf16Available() ? "bf16" : "fp32");  // auto
    // bf16 activations where the CPU has AVX-512 BF16 (a clear error elsewhere); auto picks them there.
    if (bf16Available()) {
        const RunResult bf16 = run("filter --method cnn --precision bf16 --json edge.png bf16.png", dir,
                                   "cd '" + dir.path().string() + "' &&");
        ASSERT_EQ(bf16.exitCode, 0) << bf16.err;
        EXPECT_EQ(nlohmann::json::parse(bf16.out)["precision"], "bf16");
        const RunResult fp32 = run("filter --method cnn --precision fp32 --json edge.png fp32.png", dir,
                                   "cd '" + dir.path().string() + "' &&");
        ASSERT_EQ(fp32.exitCode, 0) << fp32.err;
        EXPECT_EQ(nlohmann::json::parse(fp32.out)["precision"], "fp32");
        const Image exact = readImage(dir.file("fp32.png")), rounded = readImage(dir.file("bf16.png"));
        float worst = 0;
        for (int y = 0; y < 32; ++y)
            for (int x = 0; x < 40; ++x)
                for (int c = 0; c < 3; ++c)
                    worst = std::max(worst, std::abs(exact.at(x, y, c) - rounded.at(x, y, c)));
        EXPECT_LE(worst, 3.0f / 255.0f);
        const RunResult automatic = run("filter --method cnn --precision auto --json edge.png a.png", dir,
                                        "cd '" + dir.path().string() + "' &&");
        EXPECT_EQ(nlohmann::json::parse(automatic.out)["precision"], "bf16");
    } else {
        expectOneLineError(run("filter --method cnn --precision bf16 edge.png t.png", dir,
                               "cd '" + dir.path().string() + "' &&"),
                           "AVX-512 BF16");
    }
    expectOneLineError(run("filter --method cnn --precision half edge.png t.png", dir,
                           "cd '" + dir.path().string() + "' &&"),
                       "--precision 'half'");
    // A relative model path outside models/ is taken as given.
    expectOneLineError(run("filter --method cnn --model nowhere/dejag-fast.safetensors edge.png t.png", dir,
                           "cd '" + dir.path().string() + "' &&"),
                       "nowhere/dejag-fast.safetensors");
    // A bare name is a shipped model: dejag-guided is models/dejag-guided.safetensors, found from here too.
    const RunResult named = run("filter --method cnn --model dejag-guided --json edge.png named.png", dir,
                                "cd '" + dir.path().string() + "' &&");
    ASSERT_EQ(named.exitCode, 0) << named.err;
    EXPECT_NE(
        nlohmann::json::parse(named.out)["model"].get<std::string>().find("models/dejag-guided.safetensors"),
        std::string::npos);
    expectOneLineError(run("filter --method cnn --model no-such-model edge.png t.png", dir,
                           "cd '" + dir.path().string() + "' &&"),
                       "models/no-such-model.safetensors");
}

TEST(Cli, FilterTaaRunsOverARenderedSequence) {
    testing::TempDir dir;
    const std::string frames = dir.file("frames"), out = dir.file("out");
    ASSERT_EQ(run("render --scene corridor --size 64x48 --frames 5 --jitter halton16 "
                  "--buffers color,albedo,depth,motion,id,prevdepth --quiet --out '" +
                      frames + "'",
                  dir)
                  .exitCode,
              0);
    for (const char* method : {"taa", "taa-sobel", "taa-hq"}) {
        const RunResult r =
            run(std::string("filter --method ") + method + " '" + frames + "' '" + out + method + "' --json",
                dir);
        ASSERT_EQ(r.exitCode, 0) << r.err;
        EXPECT_EQ(nlohmann::json::parse(r.out)["frames"].size(), 5u);
        const Image last = readImage(out + method + "/frame_0004.png");
        EXPECT_EQ(last.width, 64);
        EXPECT_EQ(last.storage, PixelType::UInt16) << "a PNG from linear light keeps 16 bits";
    }
    // taa-hq reads each frame's jitter from render.json: the same offsets given as a list give the same
    // frames, and none at all (every frame taken as unjittered) others.
    {
        std::ifstream sidecar(frames + "/render.json");
        const nlohmann::json j = nlohmann::json::parse(sidecar);
        std::string list;
        for (const nlohmann::json& f : j["frames"])
            list += std::to_string(f["jitter_pixels"][0].get<double>()) + "," +
                    std::to_string(f["jitter_pixels"][1].get<double>()) + " ";
        ASSERT_EQ(run("filter --method taa-hq --quiet --set 'jitter=" + list + "' '" + frames + "' '" + out +
                          "list'",
                      dir)
                      .exitCode,
                  0);
        ASSERT_EQ(
            run("filter --method taa-hq --quiet --set 'jitter=0,0' '" + frames + "' '" + out + "zero'", dir)
                .exitCode,
            0);
        EXPECT_EQ(slurp(out + "list/frame_0004.png"), slurp(out + "taa-hq/frame_0004.png"));
        EXPECT_NE(slurp(out + "zero/frame_0004.png"), slurp(out + "taa-hq/frame_0004.png"));
    }
    // A cut restarts the history: with --cuts 3 frame 3 comes out as if the sequence began there, and
    // a gap in the numbering is a cut too.
    const RunResult cut = run("filter --method taa --cuts 3 --json '" + frames + "' '" + out + "cut'", dir);
    ASSERT_EQ(cut.exitCode, 0) << cut.err;
    const nlohmann::json cutFrames = nlohmann::json::parse(cut.out)["frames"];
    for (size_t i = 0; i < cutFrames.size(); ++i)
        EXPECT_EQ(cutFrames[i]["history_reset"].get<bool>(), i == 3) << i;
    std::filesystem::create_directories(dir.file("from3"));
    for (const char* name : {"frame_0003.exr", "frame_0004.exr", "render.json"})
        std::filesystem::copy_file(frames + "/" + name, dir.file("from3") + "/" + name);
    ASSERT_EQ(run("filter --method taa --quiet '" + dir.file("from3") + "' '" + out + "from3'", dir).exitCode,
              0);
    EXPECT_EQ(slurp(out + "cut/frame_0003.png"), slurp(out + "from3/frame_0003.png"));
    EXPECT_NE(slurp(out + "cut/frame_0003.png"), slurp(out + "taa/frame_0003.png"));
    std::filesystem::remove(dir.file("from3") + "/frame_0004.exr");
    std::filesystem::copy_file(frames + "/frame_0001.exr", dir.file("from3") + "/frame_0001.exr");
    const RunResult gap = run("filter --method taa --json '" + dir.file("from3") + "' '" + out + "gap'", dir);
    ASSERT_EQ(gap.exitCode, 0) << gap.err;
    const nlohmann::json gapFrames = nlohmann::json::parse(gap.out)["frames"];
    ASSERT_EQ(gapFrames.size(), 2u);
    EXPECT_FALSE(gapFrames[0]["history_reset"].get<bool>());
    EXPECT_TRUE(gapFrames[1]["history_reset"].get<bool>());  // 1 then 3
    expectOneLineError(run("filter --method taa --cuts 2,x '" + frames + "' '" + out + "bad'", dir),
                       "--cuts");
    EXPECT_FALSE(std::filesystem::exists(out + "bad"));
    // The optional motion blur runs over the sequence.
    const RunResult blur = run(
        "filter --method taa --motion-blur --motion-blur-scale 2 --json '" + frames + "' '" + out + "blur'",
        dir);
    ASSERT_EQ(blur.exitCode, 0) << blur.err;
    EXPECT_EQ(nlohmann::json::parse(blur.out)["frames"].size(), 5u);
    // T-TAA needs every buffer.
    const std::string colourOnly = dir.file("colour");
    ASSERT_EQ(run("render --scene corridor --size 64x48 --frames 2 --quiet --out '" + colourOnly + "'", dir)
                  .exitCode,
              0);
    expectOneLineError(run("filter --method taa-sobel '" + colourOnly + "' '" + dir.file("o") + "'", dir),
                       "depth.Z");
}

// Any EXR sequence feeds any method: a dejag render sequence with its channels renamed as Blender names
// its passes (and its motion stored the Blender way round) filters to the same frames as the original,
// OUTPUT's pattern and extension are honoured for TAA too, and a channel that is not there is one line.
TEST(Cli, FilterRunsAnyExrSequenceWithItsChannelsNamed) {
    testing::TempDir dir;
    const std::string frames = dir.file("frames");
    ASSERT_EQ(run("render --scene corridor --size 48x32 --frames 4 --jitter halton16 "
                  "--buffers color,albedo,depth,motion,id,prevdepth --quiet --out '" +
                      frames + "'",
                  dir)
                  .exitCode,
              0);
    RunResult r = run("filter --method taa --set unjitter=false --quiet '" + frames + "' '" +
                          dir.file("own/t_%04d.exr") + "'",
                      dir);  // (the renamed files below carry no jitter to un-jitter by)
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const Image own = readImage(dir.file("own/t_0003.exr"));
    EXPECT_TRUE(holdsLinearLight(own.storage)) << "an EXR holds linear light";
    EXPECT_EQ(own.channelList(), "R,G,B");
    // The same frames as Blender would name them, in a folder without render.json.
    std::ifstream sidecar(frames + "/render.json");
    const double far = nlohmann::json::parse(sidecar)["depth_far"].get<double>();
    std::filesystem::create_directories(dir.file("blend"));
    for (int i = 0; i < 4; ++i) {
        char name[32];
        std::snprintf(name, sizeof name, "frame_%04d.exr", i);
        Image frame = readImage(frames + "/" + name);
        for (std::string& channel : frame.channelNames) {
            if (channel == "R" || channel == "G" || channel == "B")
                channel = "ViewLayer.Combined." + channel;
            else if (channel == "depth.Z")
                channel = "ViewLayer.Depth.Z";
            else if (channel == "motion.X")
                channel = "ViewLayer.Vector.X";
            else if (channel == "motion.Y")
                channel = "ViewLayer.Vector.Y";
            else if (channel == "albedo.R" || channel == "albedo.G" || channel == "albedo.B")
                channel = "ViewLayer.DiffCol." + channel.substr(7);
            else if (channel == "id.ID")
                channel = "ViewLayer.IndexOB.X";
        }
        const int vx = frame.findChannel("ViewLayer.Vector.X");
        for (size_t p = 0; p < frame.pixelCount(); ++p)
            frame.pixels[p * size_t(frame.channels()) + size_t(vx)] *= -1;
        std::snprintf(name, sizeof name, "shot.%03d.exr", i + 10);
        writeImage(dir.file("blend/") + name, frame);
    }
    std::ostringstream farText;
    farText.precision(17);
    farText << far;
    r = run("filter --method taa --channels blender --depth-far " + farText.str() + " --json '" +
                dir.file("blend/shot.%03d.exr") + "' '" + dir.file("out/f_%04d.exr") + "'",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    ASSERT_EQ(j["frames"].size(), 4u);
    EXPECT_EQ(j["frames"][3]["output"], dir.file("out/f_0013.exr"));
    EXPECT_EQ(j["depth_far"]["from"], "--depth-far");
    const Image blender = readImage(dir.file("out/f_0013.exr"));
    EXPECT_EQ(blender.channelList(), "ViewLayer.Combined.R,ViewLayer.Combined.G,ViewLayer.Combined.B");
    EXPECT_EQ(blender.pixels, own.pixels) << "the same frames under other names filter the same";
    // PNG by the pattern's extension; FXAA on the same files with the colour named one by one.
    r = run("filter --method taa --channels blender --quiet '" + dir.file("blend/shot.%03d.exr") + "' '" +
                dir.file("png/f_%04d.png") + "'",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(readImage(dir.file("png/f_0012.png")).storage, PixelType::UInt16);
    r =
        run("filter --method fxaa --quiet --channel color=ViewLayer.Combined.R,ViewLayer.Combined.G,"
            "ViewLayer.Combined.B '" +
                dir.file("blend/shot.%03d.exr") + "' '" + dir.file("fxaa/f_%04d.exr") + "'",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    {
        // The buffers ride along untouched: only R G B are encoded for the method and decoded back.
        const Image in = readImage(dir.file("blend/shot.011.exr")),
                    out = readImage(dir.file("fxaa/f_0011.exr"));
        ASSERT_EQ(out.channels(), in.channels());
        for (const char* name : {"ViewLayer.DiffCol.R", "ViewLayer.Depth.Z", "ViewLayer.Vector.X"}) {
            const int a = in.findChannel(name), b = out.findChannel(name);
            ASSERT_GE(b, 0) << name;
            for (size_t p = 0; p < in.pixelCount(); ++p)
                ASSERT_EQ(out.pixels[p * size_t(out.channels()) + size_t(b)],
                          in.pixels[p * size_t(in.channels()) + size_t(a)])
                    << name;
        }
    }
    // Without render.json the far plane is the largest finite depth of the first frame.
    r = run("filter --method taa --channels blender --json '" + dir.file("blend/shot.%03d.exr") + "' '" +
                dir.file("auto/f_%04d.exr") + "'",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_GT(nlohmann::json::parse(r.out)["depth_far"]["value"].get<double>(), 0.0);
    // A channel that is not there, a buffer the method needs and dejag's names on Blender's files.
    expectOneLineError(run("filter --method taa --channels blender --channel depth=ViewLayer.Z '" +
                               dir.file("blend/shot.%03d.exr") + "' '" + dir.file("x/f_%04d.exr") + "'",
                           dir),
                       "has no channel ViewLayer.Z for the depth buffer");
    expectOneLineError(run("filter --method taa '" + dir.file("blend/shot.%03d.exr") + "' '" +
                               dir.file("x/f_%04d.exr") + "'",
                           dir),
                       "no colour channel R");
    expectOneLineError(run("filter --method taa --channel normal=N '" + dir.file("blend/shot.%03d.exr") +
                               "' '" + dir.file("x/f_%04d.exr") + "'",
                           dir),
                       "--channel");
    EXPECT_FALSE(std::filesystem::exists(dir.file("x")));
}

// The method table: --list-methods prints each method, its parameters and buffers; a parameter no method
// of the chain reads is refused before any input is read.
TEST(Cli, FilterListsItsMethodsAndRefusesParametersNoMethodReads) {
    testing::TempDir dir;
    RunResult r = run("filter --list-methods", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    for (const char* text : {"none\n", "fxaa\n", "smaa\n", "cnn\n", "taa  (temporal", "taa-sobel  (temporal",
                             "taa-hq  (temporal", "cnn-temporal  (temporal", "static-lock = true",
                             "preset = 39", "gate = auto", "needs: depth, motion", "feedback-max = 0.979"})
        EXPECT_NE(r.out.find(text), std::string::npos) << text;
    r = run("filter --list-methods --json", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(nlohmann::json::parse(r.out).size(),
              8u);  // none, fxaa, smaa, cnn, taa, taa-sobel, taa-hq, cnn-temporal
    Image edge(24, 20, {"R", "G", "B"}, PixelType::UInt8);
    for (int y = 0; y < 20; ++y)
        for (int x = 0; x < 24; ++x)
            for (int c = 0; c < 3; ++c) edge.at(x, y, c) = y > 0.4 * x + 5 ? 1.0f : 0.0f;
    writeImage(dir.file("edge.png"), edge);
    expectOneLineError(
        run("filter --method cnn --preset 12 '" + dir.file("edge.png") + "' '" + dir.file("o.png") + "'",
            dir),
        "--preset: cnn has no parameter 'preset'");
    expectOneLineError(run("filter --method fxaa --set subpixel=0.5 '" + dir.file("edge.png") + "' '" +
                               dir.file("o.png") + "'",
                           dir),
                       "--set subpixel=0.5");
    r = run("filter --method fxaa --set subpix=0.25 --set edge-threshold=0.2 --json '" +
                dir.file("edge.png") + "' '" + dir.file("o.png") + "'",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    expectOneLineError(
        run("filter --method fxaa --cuts 3 '" + dir.file("edge.png") + "' '" + dir.file("o.png") + "'", dir),
        "keeps no history");
    // SMAA by preset name, a setting of its own, and a bad preset, a bad setting, predication without depth.
    r = run("filter --method smaa --preset high --set corner-rounding=50 '" + dir.file("edge.png") + "' '" +
                dir.file("s.png") + "'",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(readImage(dir.file("s.png")).pixels, readImage(dir.file("edge.png")).pixels);
    expectOneLineError(run("filter --method smaa --preset extreme '" + dir.file("edge.png") + "' '" +
                               dir.file("s.png") + "'",
                           dir),
                       "--preset: SMAA preset 'extreme' is not one of low, medium, high, ultra");
    expectOneLineError(run("filter --method smaa --set search-steps=500 '" + dir.file("edge.png") + "' '" +
                               dir.file("s.png") + "'",
                           dir),
                       "search-steps");
    expectOneLineError(run("filter --method smaa --set predication=on '" + dir.file("edge.png") + "' '" +
                               dir.file("p.png") + "'",
                           dir),
                       "depth");
}

TEST(Cli, BenchFilterPrintsEveryMethod) {
    testing::TempDir dir;
    // (No networks: --models '' and --temporal-model '' leave out the shipped ones, found from any folder.)
    const RunResult r =
        run("bench filter --size 96x64 --repeat 1 --threads 1 --json --models '' --temporal-model ''", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::vector<std::string> names;
    for (const nlohmann::json& j : jsonLines(r.out)) {
        EXPECT_GT(j["ms"].get<double>(), 0.0);
        EXPECT_GT(j["floor_ms"].get<double>(), 0.0);
        names.push_back(j["name"].get<std::string>());
    }
    EXPECT_EQ(names,
              (std::vector<std::string>{"fxaa preset 12", "fxaa preset 23", "fxaa preset 39", "smaa low",
                                        "smaa medium", "smaa high", "smaa ultra", "u-taa", "u-taa zoom",
                                        "u-taa random motion", "t-taa", "t-taa zoom", "t-taa random motion",
                                        "taa-hq", "taa-hq zoom", "taa-hq random motion"}));
    // A guided single-frame network: gated and ungated, with its guide method timed and given.
    const RunResult g =
        run("bench filter --size 96x64 --repeat 1 --threads 1 --json --temporal-model '' "
            "--models '" DEJAG_SOURCE_DIR "/models/dejag-guided.safetensors'",
            dir);
    ASSERT_EQ(g.exitCode, 0) << g.err;
    std::set<std::string> networks;
    for (const nlohmann::json& j : jsonLines(g.out))
        if (j.contains("macs_per_pixel")) {
            networks.insert(j["name"].get<std::string>());
            EXPECT_GT(j["psnr_after"].get<double>(), j["psnr_before"].get<double>()) << j.dump();
        }
    for (const char* name : {"dejag-guided fp32", "dejag-guided fp32 (smaa given)",
                             "dejag-guided fp32 ungated", "dejag-guided fp32 ungated (smaa given)"})
        EXPECT_TRUE(networks.count(name)) << name;
    expectOneLineError(run("bench filter --size 96x64 --models nowhere.safetensors", dir), "nowhere");
}

TEST(Cli, BenchReachScoresEdgePixelsByRunLength) {
    testing::TempDir dir;
    const RunResult r = run("bench reach --size 200x120 --scenes pipe --truth 4 --models '' --json", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::set<std::string> methods, runs;
    int rows = 0;
    double fxaaGain = -100;
    for (const nlohmann::json& j : jsonLines(r.out)) {
        ++rows;
        methods.insert(j["method"].get<std::string>());
        runs.insert(j["run"].get<std::string>());
        if (j["method"] == "no AA") {
            EXPECT_EQ(j["gain_db"].get<double>(), 0.0);
        }
        if (j["method"] == "FXAA" && j["scene"] == "all" && j["pixels"].get<int64_t>() > 0)
            fxaaGain = std::max(fxaaGain, j["gain_db"].get<double>());
    }
    EXPECT_EQ(methods, (std::set<std::string>{"no AA", "FXAA", "SMAA"}));
    EXPECT_EQ(runs, (std::set<std::string>{"1-3", "4-15", "16-63", "64+", "frame", "texture"}));
    EXPECT_EQ(rows, 2 * 6 * 3);  // pipe and all, 4 run classes + frame + texture, 3 methods
    EXPECT_GT(fxaaGain, 0.5);
    expectOneLineError(run("bench reach --scenes nowhere", dir), "nowhere");
}

TEST(Cli, BenchStabilityChecksEveryKindWithinTolerance) {
    testing::TempDir dir;
    const RunResult r =
        run("bench stability --configs 90 --seed 3 --json --frame 96x64 --denormal-frame 64x48 "
            "--repeat 1 --training-steps 3 --model '" DEJAG_SOURCE_DIR "/models/dejag-fast.safetensors'",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    int kinds = 0;
    bool accumulation = false, denormals = false, determinism = false;
    int degenerate = 0;
    for (const nlohmann::json& j : jsonLines(r.out)) {
        if (j["kind"] == "accumulation") {
            accumulation = true;
            EXPECT_EQ(j["model"], "dejag-fast");
            EXPECT_LE(j["normwise_relative_error"].get<double>(), 1e-5) << j.dump();
            EXPECT_GT(j["normwise_relative_error"].get<double>(), 0.0)
                << "float32 cannot equal double" << j.dump();
            continue;
        }
        if (j["kind"].get<std::string>().rfind("ssim degenerate: ", 0) == 0) {
            ++degenerate;
            EXPECT_TRUE(j["passed"].get<bool>()) << j.dump();
            continue;
        }
        if (j["kind"] == "determinism") {
            determinism = true;
            EXPECT_TRUE(j["training_repeatable"].get<bool>()) << j.dump();
            EXPECT_TRUE(j["inference_repeatable"].get<bool>()) << j.dump();
            EXPECT_LE(j["inference_across_threads"].get<double>(), 1e-5) << j.dump();
            EXPECT_LE(j["training_across_threads"].get<double>(), 1e-3) << j.dump();
            continue;
        }
        if (j["kind"] == "denormals") {
            denormals = true;
            EXPECT_GT(j["normal_ms"].get<double>(), 0.0) << j.dump();
            EXPECT_GT(j["denormal_ms"].get<double>(), 0.0) << j.dump();
            continue;
        }
        ++kinds;
        EXPECT_EQ(j["configurations"], 10) << j.dump();
        EXPECT_GT(j["coordinates"].get<int>(), 0) << j.dump();
        EXPECT_LE(j["worst_gradient_error"].get<double>(), 1e-6) << j.dump();
        EXPECT_EQ(j["over_tolerance"], 0) << j.dump();
    }
    EXPECT_EQ(kinds, 9);
    EXPECT_TRUE(accumulation);
    EXPECT_TRUE(denormals);
    EXPECT_EQ(degenerate, 7);
    EXPECT_TRUE(determinism);
}

TEST(Cli, BenchTaaReproducesTheThesisProtocolsSmall) {
    testing::TempDir dir;
    const RunResult r =
        run("bench taa --size 64x36 --truth 4 --ghost-frames 2 --ghost-size 32x18 --ghost-truth 2 "
            "--moving-frames 3 --fast-model '' --temporal-model '' "  // the methods without the networks
            "--json "
            "--out '" +
                dir.file("maps") + "'",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    int statics = 0, ghosts = 0, moving = 0;
    std::set<std::string> staticMethods, ghostMethods;
    for (const nlohmann::json& j : jsonLines(r.out)) {
        if (j["test"] == "static") {
            ++statics;
            staticMethods.insert(j["method"].get<std::string>());
            EXPECT_TRUE(std::filesystem::exists(dir.file("maps") + "/" + j["ssim_map"].get<std::string>()));
            EXPECT_GT(j["ssim"].get<double>(), 0.0);
        } else {
            ++(j["test"] == "moving" ? moving : ghosts);
            ghostMethods.insert(j["method"].get<std::string>());
            EXPECT_LE(j["psnr"]["worst"].get<double>(), j["psnr"]["mean"].get<double>());
            EXPECT_GE(j["flicker"].get<double>(), 0.0);
        }
    }
    EXPECT_EQ(statics, 9 * 9);
    EXPECT_EQ(ghosts, 3 * 8);
    EXPECT_EQ(moving, 4 * 3 * 8);  // 4 scenes, 3 camera motions, 8 methods
    for (const char* m : {"no aa", "fxaa", "smaa", "u-taa", "t-taa", "taa-hq", "oracle"})
        EXPECT_EQ(staticMethods.count(m), 1u) << m;
    for (const char* m : {"no aa", "fxaa", "smaa", "u-taa", "t-taa", "taa-hq"})
        EXPECT_EQ(ghostMethods.count(m), 1u) << m;
    // The table prints every protocol.
    const RunResult text =
        run("bench taa --size 64x36 --truth 2 --ghost-frames 2 --ghost-size 32x18 --ghost-truth 2 "
            "--moving-frames 2",
            dir);
    ASSERT_EQ(text.exitCode, 0) << text.err;
    for (const char* want : {"oracle", "ghosting corridor", "moving pipe", "orbit 1 px"})
        EXPECT_NE(text.out.find(want), std::string::npos) << want;
}

// --scenes keeps only the named scenes in every test; --moving-scenes puts other scenes under the moving
// camera; a name that is no scene, or that names none of the tests' scenes, is one line.
TEST(Cli, BenchTaaRunsTheScenesItIsGiven) {
    testing::TempDir dir;
    const RunResult r =
        run("bench taa --size 64x36 --truth 2 --frames 16 --ghost-size 32x18 --ghost-truth 2 "
            "--moving-frames 2 --scenes flowers,blinds --moving-scenes flowers,blinds --json",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::set<std::string> seen;
    for (const nlohmann::json& j : jsonLines(r.out)) {
        seen.insert(j["test"].get<std::string>() + " " + j["scene"].get<std::string>());
    }
    EXPECT_EQ(seen,
              (std::set<std::string>{"static flowers", "static blinds", "moving flowers", "moving blinds"}));
    expectOneLineError(run("bench taa --moving-scenes nope --no-ghosting", dir), "unknown scene 'nope'");
    expectOneLineError(run("bench taa --scenes nope", dir), "no scene of the protocols");
}

TEST(Cli, RenderListsTheScenes) {
    testing::TempDir dir;
    const RunResult r = run("render --list", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    for (const char* scene : {"pipe", "blinds", "hairball-lit-rotating", "planes", "zone-plate", "random"})
        EXPECT_NE(r.out.find(scene), std::string::npos) << scene;
}

// A network trained after SMAA, or reading it beside the frame: the model records it, dejag filter runs
// SMAA first (tests/infer/cnn_test.cpp checks the outputs), its card says so, and a method that needs
// buffers, or a network that cannot take a guide, is refused.
TEST(Cli, TrainAfterAnInputMethodRecordsIt) {
    testing::TempDir dir;
    const std::string data = dir.file("data"), runFolder = dir.file("run");
    ASSERT_EQ(
        run("data generate --families shapes,pipes,foliage --test-families foliage --count 9 --size 64x64 "
            "--truth 4 --quiet --out '" +
                data + "'",
            dir)
            .exitCode,
        0);
    const std::string train = "train --data '" + data +
                              "' --arch kpn:8x2 --steps 4 --batch 2 --patch 32 "
                              "--eval-every 2 --checkpoint-every 2 --val-images 2 --quiet --input-method ";
    RunResult r = run(train + "smaa --out '" + runFolder + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(nn::loadModel(runFolder + "/final.safetensors").architecture().value("input_method", ""),
              "smaa");
    r = run("train export '" + runFolder + "' '" + dir.file("m.safetensors") + "' --quiet", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::ifstream card(dir.file("m.md"));
    std::stringstream text;
    text << card.rdbuf();
    EXPECT_NE(text.str().find("The network runs after smaa"), std::string::npos);
    expectOneLineError(run(train + "taa --out '" + dir.file("run2") + "'", dir), "--input-method: taa");
    expectOneLineError(run(train + "blur --out '" + dir.file("run3") + "'", dir), "blur");
    // Beside the frame instead: the kpn family takes the guide, the card says so, the filter runs it.
    const std::string guided = dir.file("guided");
    const std::string besides = "train --data '" + data +
                                "' --arch kpn:8x2 --steps 4 --batch 2 --patch 32 --eval-every 2 "
                                "--checkpoint-every 2 --val-images 2 --quiet ";
    // (with the harm terms, the one on texture pixels too: the patches then carry their texture masks)
    r = run(besides + "--guide-method smaa --loss 'ssim+0.1*harm+0.1*texharm' --out '" + guided + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const nn::Model model = nn::loadModel(guided + "/final.safetensors");
    EXPECT_EQ(model.architecture().value("guide_method", ""), "smaa");
    EXPECT_EQ(model.inputChannels(), 6);
    r = run("train export '" + guided + "' '" + dir.file("g.safetensors") + "' --quiet", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::ifstream guidedCard(dir.file("g.md"));
    std::stringstream guidedText;
    guidedText << guidedCard.rdbuf();
    EXPECT_NE(guidedText.str().find("The network reads smaa's result beside the frame"), std::string::npos);
    expectOneLineError(run(besides + "--guide-method taa --out '" + dir.file("run4") + "'", dir),
                       "--guide-method: taa");
    expectOneLineError(
        run(besides + "--guide-method smaa --input-method smaa --out '" + dir.file("run5") + "'", dir),
        "choose one");
    expectOneLineError(run("train --data '" + data +
                               "' --arch fast:8x2 --steps 4 --batch 2 --patch 32 --quiet "
                               "--guide-method smaa --out '" +
                               dir.file("run6") + "'",
                           dir),
                       "6 channels");
    expectOneLineError(run("train --data '" + data +
                               "' --arch kpn:8x2+guide --steps 4 --batch 2 --patch 32 "
                               "--quiet --out '" +
                               dir.file("run7") + "'",
                           dir),
                       "--guide-method");
}

// Nine 64x64 items of three families, foliage held out for the test split: a dataset for short runs.
int generateTinyDataset(const std::string& folder, const testing::TempDir& dir) {
    return run("data generate --families shapes,pipes,foliage --test-families foliage --count 9 --size 64x64 "
               "--truth 8 --quiet --out '" +
                   folder + "'",
               dir)
        .exitCode;
}

// On a terminal (a pseudo-terminal from script(1)) the training progress bar and the log lines share the
// screen cleanly: a log line clears the bar first, so no line shows both. After --resume the bar's rate
// counts only the new steps.
TEST(Cli, TrainProgressBarAndLogLinesShareATerminal) {
    testing::TempDir dir;
    const std::string data = dir.file("data"), runFolder = dir.file("run");
    ASSERT_EQ(generateTinyDataset(data, dir), 0);
    auto onTerminal = [&](int steps, bool resume) {
        const std::string screen = dir.file("screen.txt");
        const std::string command =
            "script -qec \"'" + std::string(DEJAG_BINARY) + "' train --data '" + data + "' --out '" +
            runFolder + "' --arch fast --steps " + std::to_string(steps) +
            " --batch 2 --patch 32 --eval-every 50 --checkpoint-every 50 --val-images 2" +
            (resume ? " --resume" : "") + "\" /dev/null >'" + screen + "' 2>&1";
        EXPECT_EQ(std::system(command.c_str()), 0);
        return slurp(screen);
    };
    // What each screen line finally shows: the text after its last carriage return.
    auto screenLines = [](const std::string& text) {
        std::vector<std::string> lines;
        std::istringstream in(text);
        for (std::string line; std::getline(in, line);) {
            while (!line.empty() && line.back() == '\r') line.pop_back();
            const size_t cr = line.rfind('\r');
            lines.push_back(cr == std::string::npos ? line : line.substr(cr + 1));
        }
        return lines;
    };
    auto rates = [](const std::string& text) {  // every "N.NN/s" the bar drew, in order
        std::vector<double> found;
        for (size_t at = text.find("/s  "); at != std::string::npos; at = text.find("/s  ", at + 1)) {
            const size_t start = text.rfind(' ', at);
            found.push_back(std::atof(text.substr(start + 1, at - start - 1).c_str()));
        }
        return found;
    };
    std::vector<double> freshRates;
    for (const auto& [steps, resume] : {std::pair{150, false}, std::pair{300, true}}) {
        SCOPED_TRACE(resume ? "resumed" : "fresh");
        const std::string text = onTerminal(steps, resume);
        int logLines = 0;
        for (const std::string& line : screenLines(text)) {
            const bool log = line.find("val PSNR") != std::string::npos;
            logLines += log;
            EXPECT_FALSE(log && line.find("ETA") != std::string::npos) << line;
            EXPECT_EQ(line.find("nan"), std::string::npos) << line;  // nothing to measure is "-"
        }
        EXPECT_EQ(logLines, 3);
        const std::vector<double> drawn = rates(text);
        ASSERT_GE(drawn.size(), 2u) << text;
        if (!resume) {
            freshRates = drawn;
            continue;
        }
        // The resumed session's first bar: counting the 150 resumed steps as done in its first moment made
        // it 1,500/s above the true rate (7x the fresh session's); the rate swings with the machine's load,
        // hence the margin.
        EXPECT_LE(drawn.front(), 4.0 * *std::max_element(freshRates.begin(), freshRates.end())) << text;
    }
}

TEST(Cli, TrainLogsJsonResumesAndExportsAModelCard) {
    testing::TempDir dir;
    const std::string data = dir.file("data"), runFolder = dir.file("run");
    ASSERT_EQ(generateTinyDataset(data, dir), 0);
    const std::string train =
        "train --data '" + data + "' --out '" + runFolder +
        "' --arch fast --steps 8 --batch 2 --patch 32 --eval-every 4 --checkpoint-every 4 "
        "--val-images 2 --quiet --json";
    RunResult r = run(train, dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    int evaluations = 0;
    nlohmann::json last;
    for (const nlohmann::json& j : jsonLines(r.out)) {
        last = j;
        if (last["event"] == "evaluation") {
            ++evaluations;
            EXPECT_TRUE(last.contains("psnr_whole") && last.contains("baseline_psnr_FXAA")) << last.dump();
        }
    }
    EXPECT_EQ(evaluations, 2);
    EXPECT_EQ(last["event"], "finished");
    EXPECT_EQ(last["steps"], 8);
    // The same folder again: refused without --resume; with it, nothing left to do.
    expectOneLineError(run(train, dir), "--resume");
    EXPECT_EQ(run(train + " --resume", dir).exitCode, 0);

    const std::string model = dir.file("tiny.safetensors");
    r = run("train export '" + runFolder + "' '" + model + "' --quiet", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_TRUE(std::filesystem::exists(model));
    std::ifstream card(dir.file("tiny.md"));
    std::stringstream text;
    text << card.rdbuf();
    EXPECT_NE(text.str().find("| FXAA |"), std::string::npos);
    EXPECT_NE(text.str().find("dejag train --data"), std::string::npos) << "the card records the command";

    // With the rows `bench taa --json` printed (here a few written by hand): the card carries their means,
    // per test, and the static test scene by scene. A file that is not such rows: one line, no model.
    const std::string bench = dir.file("bench.json");
    {
        std::ofstream rows(bench);
        rows
            << R"({"test":"static","scene":"pipe","method":"no aa","psnr":30.0,"ssim":0.9,"width":80,"height":48,"jitter_spread":1.0})"
            << "\n"
            << R"({"test":"static","scene":"flowers","method":"no aa","psnr":32.0,"ssim":0.8,"width":80,"height":48})"
            << "\n"
            << R"({"test":"moving","scene":"pipe","method":"taa-hq","motion":"pan 1 px","psnr":{"best":40,"mean":36.5,"worst":30},"ssim":{"best":1,"mean":0.95,"worst":0.9},"flicker":0.004})"
            << "\n";
    }
    r = run("train export '" + runFolder + "' '" + model + "' --quiet --bench-taa '" + bench + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::ifstream benchCard(dir.file("tiny.md"));
    std::stringstream withBench;
    withBench << benchCard.rdbuf();
    EXPECT_NE(withBench.str().find("| no aa | 31.00 | 0.8500 |"), std::string::npos) << withBench.str();
    EXPECT_NE(withBench.str().find("| taa-hq | 36.50 | 0.9500 | 0.00400 |"), std::string::npos);
    EXPECT_NE(withBench.str().find("| flowers | 32.00 |"), std::string::npos);
    EXPECT_NE(withBench.str().find("jitter spread 1 px"), std::string::npos);
    {
        std::ofstream rows(dir.file("bad.json"));
        rows
            << R"({"test":"static","scene":"pipe","method":"no aa","psnr":30.0,"ssim":0.9,"width":80,"height":48})"
            << "\nnot json\n";
    }
    const std::string other = dir.file("other.safetensors");
    expectOneLineError(
        run("train export '" + runFolder + "' '" + other + "' --bench-taa '" + dir.file("bad.json") + "'",
            dir),
        "line 2");
    expectOneLineError(
        run("train export '" + runFolder + "' '" + other + "' --bench-taa '" + dir.file("none.json") + "'",
            dir),
        "none.json");
    EXPECT_FALSE(std::filesystem::exists(other));
}

TEST(Cli, TrainBadInputIsOneLine) {
    testing::TempDir dir;
    expectOneLineError(run("train --out '" + dir.file("r") + "' --steps 5", dir), "--data");
    expectOneLineError(
        run("train --data '" + dir.file("nothing") + "' --out '" + dir.file("r") + "' --steps 5", dir),
        "nothing");
    expectOneLineError(run("train --data x --out '" + dir.file("r") + "' --arch nosuch --steps 5", dir),
                       "nosuch");
    expectOneLineError(run("train --data x --out '" + dir.file("r") + "' --steps 5 --patch 30", dir),
                       "--patch");
    expectOneLineError(run("train --data x --out '" + dir.file("r") + "' --steps 5 --loss ssim+typo", dir),
                       "typo");
    expectOneLineError(run("train --data x --out '" + dir.file("r") + "'", dir), "--steps");
    expectOneLineError(
        run("train export '" + dir.file("norun") + "' '" + dir.file("m.safetensors") + "'", dir), "norun");
    EXPECT_FALSE(std::filesystem::exists(dir.file("m.safetensors")));
}

// A small randomly initialised RGB network of the fast family, saved as a model file.
std::string writeTinyModel(const std::string& path, uint64_t seed) {
    nn::Model m = nn::Model::builtin("fast", {4, 2, 3});
    m.initialize(seed);
    nn::saveModel(path, m);
    return path;
}

TEST(Cli, DemoRunsEveryMethodAndWritesTheReport) {
    testing::TempDir dir;
    const std::string model = writeTinyModel(dir.file("tiny.safetensors"), 1);
    // A second model of the same file name (a new version, say): its rows stay apart, named by folder.
    std::filesystem::create_directories(dir.file("v2"));
    const std::string version2 = writeTinyModel(dir.file("v2/tiny.safetensors"), 2);
    // The moving sequence's temporal network: an untrained one of the built-in family.
    nn::Model temporal = nn::Model::builtin("temporal", {4, 2, 3, 1});
    temporal.initialize(3);
    nn::saveModel(dir.file("temporal.safetensors"), temporal);
    const std::string out = dir.file("demo");
    const RunResult r =
        run("demo --out '" + out +
                "' --size 96x64 --truth 8 --scenes pipe,flowers --repeat 1 --quiet --json --models '" +
                model + "," + version2 + "," + dir.file("missing.safetensors") + "' --temporal-model '" +
                dir.file("temporal.safetensors") + "' --moving-frames 4",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.err.find("missing.safetensors not found"), std::string::npos) << r.err;
    std::set<std::string> methods, moving;
    int rows = 0;
    for (const nlohmann::json& j : jsonLines(r.out)) {
        if (j.value("test", "") == "moving") {
            moving.insert(j["method"].get<std::string>());
            EXPECT_EQ(j["scored_from"], 2);
            EXPECT_GT(j["psnr"].get<double>(), 10.0);
            continue;
        }
        methods.insert(j["method"].get<std::string>());
        ++rows;
        if (j["method"] == "no AA" && j["scene"] != "mean") {
            EXPECT_LT(j["psnr_whole"].get<double>(), 60.0);
        }
    }
    const std::string first = dir.path().filename().string() + "/tiny";
    std::set<std::string> expected{"no AA",
                                   "FXAA",
                                   "SMAA",
                                   "U-TAA",
                                   "T-TAA",
                                   "T-TAA unsharpened",
                                   "taa-hq",
                                   first,
                                   first + " (ungated)",
                                   "v2/tiny",
                                   "v2/tiny (ungated)"};
    if (bf16Available())  // each RGB network also with bf16 activations
        expected.insert(
            {first + " bf16", first + " bf16 (ungated)", "v2/tiny bf16", "v2/tiny bf16 (ungated)"});
    EXPECT_EQ(methods, expected);
    EXPECT_EQ(rows, 3 * int(expected.size()));
    EXPECT_EQ(moving, (std::set<std::string>{"no AA", "FXAA", "taa-hq", "dejag-temporal"}));
    for (const char* f : {"report.html", "mosaic.png", "pareto.png", "results.csv", "results.json",
                          "images/pipe_FXAA_crop.png", "images/flowers_v2-tiny_ssim.png", "moving.png"})
        EXPECT_TRUE(std::filesystem::exists(out + "/" + f)) << f;
    expectOneLineError(run("demo --out '" + dir.file("d2") + "' --scenes teapot", dir), "teapot");
    std::ofstream(dir.file("bad.safetensors")) << "garbage";
    expectOneLineError(
        run("demo --out '" + dir.file("d2") + "' --models '" + dir.file("bad.safetensors") + "'", dir),
        "bad.safetensors");
    EXPECT_FALSE(std::filesystem::exists(dir.file("d2")));
}

// The report in a browser (headless Chromium, installed by scripts/install-deps): it renders, and its
// viewer's flip control, clicked by the page itself when opened with #flip=0, changes the picture where
// the two methods differ and nowhere when they are the same.
TEST(Cli, ReportRendersInChromiumAndItsFlipShowsTheOtherMethod) {
    testing::TempDir dir;
    const std::string browser = "/usr/bin/chromium-headless-shell";
    ASSERT_TRUE(std::filesystem::exists(browser)) << "scripts/install-deps installs chromium-headless-shell";
    const std::string out = dir.file("demo");
    // (Run outside the source tree: the shipped temporal network is found from any folder.)
    const RunResult r = run(
        "demo --out '" + out + "' --size 96x64 --truth 8 --scenes pipe --repeat 1 --quiet --moving-frames 4",
        dir, "cd / &&");
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(slurp(out + "/report.html").find("no temporal model"), std::string::npos);
    const auto screenshot = [&](const std::string& fragment, const std::string& name) {
        const std::string png = dir.file(name);
        const std::string command =
            "cd '" + dir.path().string() + "' && '" + browser +
            "' --no-sandbox --disable-gpu --hide-scrollbars --virtual-time-budget=3000 "
            "--window-size=1000,1400 --screenshot='" +
            png + "' 'file://" + out + "/report.html" + fragment + "' >/dev/null 2>&1";
        EXPECT_EQ(std::system(command.c_str()), 0) << command;
        return readImage(png);
    };
    const auto differing = [](const Image& a, const Image& b) {
        size_t n = 0;
        for (size_t i = 0; i < a.pixels.size(); ++i) n += a.pixels[i] != b.pixels[i];
        return n;
    };
    const Image swiped = screenshot("#view=0&a=no%20AA&b=truth", "swiped.png");
    const Image flipped = screenshot("#flip=0&a=no%20AA&b=truth", "flipped.png");
    ASSERT_EQ(swiped.pixels.size(), flipped.pixels.size());
    // It rendered: not a blank page (the table, the plot and the crops are there).
    const Image page = screenshot("", "page.png");
    size_t dark = 0;
    for (float v : page.pixels) dark += v < 0.5f;
    EXPECT_GT(dark, page.pixels.size() / 100);
    const Image same = screenshot("#view=0&a=truth&b=truth", "same.png");
    const Image sameFlipped = screenshot("#flip=0&a=truth&b=truth", "same_flipped.png");
    // With the same method on both sides only the caption naming what is shown changes; with no AA over
    // the truth, no AA's half of the viewer (480 px wide, 4x zoomed pixels) becomes the truth's too.
    const size_t captionOnly = differing(same, sameFlipped), methods = differing(swiped, flipped);
    EXPECT_LT(captionOnly, 3000u);
    EXPECT_GT(methods, captionOnly + 3000) << captionOnly;
}

// The largest difference, in 8-bit steps, between a screenshot and an image, over the columns [x0, x1).
int largestStep(const Image& shot, const Image& expected, int x0, int x1) {
    EXPECT_EQ(shot.width, expected.width);
    EXPECT_EQ(shot.height, expected.height);
    int largest = 0;
    for (int y = 0; y < shot.height; ++y)
        for (int x = x0; x < x1; ++x)
            for (int c = 0; c < 3; ++c)
                largest = std::max(largest, int(std::abs(std::lround(shot.at(x, y, c) * 255) -
                                                         std::lround(expected.at(x, y, c) * 255))));
    return largest;
}

// dejag bench glsl: every GPU form beside its CPU filter on rendered frames, each pass timed, the OpenGL
// renderer named (off screen: no display needed).
TEST(Cli, BenchGlslTimesEveryGpuPassBesideTheCpuFilter) {
    testing::TempDir dir;
    const RunResult r =
        run("bench glsl --size 64x48 --repeat 2 --json --methods none,smaa,taa-hq,cnn-temporal", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const std::vector<nlohmann::json> rows = jsonLines(r.out);
    ASSERT_EQ(rows.size(), 4u) << r.out;
    const size_t passes[] = {1, 3, 2,
                             0};  // none: its copy; smaa: 3; taa-hq: 2 (no sharpen); the network: many
    for (size_t k = 0; k < rows.size(); ++k) {
        EXPECT_EQ(rows[k]["frames"], 2);
        EXPECT_GT(rows[k]["gpu_ms"].get<double>(), 0.0) << rows[k].dump();
        EXPECT_GT(rows[k]["cpu_ms"].get<double>(), 0.0) << rows[k].dump();
        if (passes[k]) {
            EXPECT_EQ(rows[k]["passes"].size(), passes[k]) << rows[k].dump();
        }
        EXPECT_NE(rows[k]["opengl"].get<std::string>().find("OSMesa"), std::string::npos);
    }
    EXPECT_GT(rows[3]["passes"].size(), 10u);
    expectOneLineError(run("bench glsl --methods fxaa,nothing", dir), "nothing");
}

// dejag view under a virtual display (xvfb-run, installed by scripts/install-deps): a script switches
// the method to FXAA, and the screenshot of the third frame equals what dejag render then dejag filter
// make of that frame (same jitter) within 1/255, whether FXAA ran as its GLSL form on the rendered frame
// or on the CPU; so does the network's GLSL form; a split screen shows the two methods side by side, and
// paused, key t puts the accumulated truth beside the method. Without a display: one error line.
TEST(Cli, ViewShowsWhatTheFilterWrites) {
    testing::TempDir dir;
    ASSERT_TRUE(std::filesystem::exists("/usr/bin/xvfb-run")) << "scripts/install-deps installs xvfb";
    expectOneLineError(run("view --scene pipe --frames 1", dir, "env -u DISPLAY -u WAYLAND_DISPLAY"),
                       "no display");
    std::ofstream(dir.file("keys.txt")) << "# switch to FXAA at the second frame\n1 2\n";
    // Under ASan, leak checking is off for the window's runs: Mesa's GLX driver, unloaded when the window
    // closes, leaves a few hundred bytes whose frames no suppression can name (an "unknown module").
    const std::string xvfb = "ASAN_OPTIONS=detect_leaks=0 xvfb-run -a -s '-screen 0 320x240x24' ";
    const std::string view = "view --scene pipe --size 96x64 --frames 3 --no-overlay ";
    RunResult r = run(view + "--method none --device gpu --script '" + dir.file("keys.txt") +
                          "' --screenshot '" + dir.file("gpu.png") + "'",
                      dir, xvfb);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    r = run(view + "--method fxaa --device cpu --screenshot '" + dir.file("cpu-shot.png") + "'", dir, xvfb);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    r = run(view + "--method cnn --device gpu --json --screenshot '" + dir.file("cnn.png") + "'", dir, xvfb);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    {  // --json: the method's median and each of its GPU passes' (the input pass, the layers, the output)
        const std::vector<nlohmann::json> rows = jsonLines(r.out);
        ASSERT_EQ(rows.size(), 1u) << r.out;
        EXPECT_EQ(rows[0]["method"], "cnn");
        EXPECT_EQ(rows[0]["frames"], 3);
        ASSERT_GE(rows[0]["passes"].size(), 4u);
        EXPECT_EQ(rows[0]["passes"][0]["name"], "network input");
        EXPECT_EQ(rows[0]["passes"].back()["name"], "network output");
    }
    r =
        run("render --scene pipe --size 96x64 --frames 3 --jitter halton16 --buffers "
            "color,albedo,depth,motion,id,prevdepth --truth 64 --quiet --out '" +
                dir.file("r") + "'",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    for (const std::string method : {"fxaa", "cnn --gate off --precision fp32"}) {
        r = run("filter --method " + method + " --quiet '" + dir.file("r/frame_0002.exr") + "' '" +
                    dir.file(method.substr(0, 4) + ".png") + "'",
                dir);
        ASSERT_EQ(r.exitCode, 0) << r.err;
    }
    const Image cpu = readImage(dir.file("fxaa.png")), unfiltered = readImage(dir.file("r/frame_0002.png"));
    EXPECT_LE(largestStep(readImage(dir.file("gpu.png")), cpu, 0, 96), 1);
    EXPECT_LE(largestStep(readImage(dir.file("cpu-shot.png")), cpu, 0, 96), 1);
    EXPECT_LE(largestStep(readImage(dir.file("cnn.png")), readImage(dir.file("cnn .png")), 0, 96), 1);
    // --model: key 7's network, here dejag-guided, whose GPU form runs SMAA's first.
    r = run("filter --method cnn --model dejag-guided --gate off --precision fp32 --quiet '" +
                dir.file("r/frame_0002.exr") + "' '" + dir.file("guided.png") + "'",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    r = run(view + "--method cnn --model dejag-guided --device gpu --screenshot '" +
                dir.file("guided-gpu.png") + "'",
            dir, xvfb);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_LE(largestStep(readImage(dir.file("guided-gpu.png")), readImage(dir.file("guided.png")), 0, 96),
              1);
    expectOneLineError(run(view + "--method cnn --model nosuch", dir, xvfb), "nosuch");
    // taa-hq over the three frames, its history on the GPU or on the CPU, against dejag filter on the
    // rendered sequence (each frame's jitter from render.json).
    r = run("filter --method taa-hq --quiet '" + dir.file("r") + "' '" + dir.file("taa") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const Image taa = readImage(dir.file("taa/frame_0002.png"));
    for (const std::string device : {"gpu", "cpu"}) {
        r = run(view + "--method taa-hq --device " + device + " --screenshot '" +
                    dir.file("taa-" + device + ".png") + "'",
                dir, xvfb);
        ASSERT_EQ(r.exitCode, 0) << r.err;
        EXPECT_LE(largestStep(readImage(dir.file("taa-" + device + ".png")), taa, 0, 96), 1) << device;
    }
    EXPECT_GT(largestStep(taa, unfiltered, 0, 96), 8);
    // T-TAA's GPU form likewise (the Sobel's own history on the GPU too).
    r = run("filter --method taa-sobel --quiet '" + dir.file("r") + "' '" + dir.file("tsobel") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    r = run(view + "--method taa-sobel --device gpu --screenshot '" + dir.file("tsobel.png") + "'", dir,
            xvfb);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_LE(
        largestStep(readImage(dir.file("tsobel.png")), readImage(dir.file("tsobel/frame_0002.png")), 0, 96),
        1);
    // The methods did change the frame, so the matches say something.
    EXPECT_GT(largestStep(cpu, unfiltered, 0, 96), 8);
    EXPECT_GT(largestStep(readImage(dir.file("cnn .png")), unfiltered, 0, 96), 8);
    // Split: none on the left half, FXAA on the right.
    r = run(view + "--method none --compare fxaa --screenshot '" + dir.file("split.png") + "'", dir, xvfb);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const Image split = readImage(dir.file("split.png"));
    EXPECT_LE(largestStep(split, unfiltered, 0, 47), 1);  // 47 and 48: the dividing line
    EXPECT_LE(largestStep(split, cpu, 49, 96), 1);
    // Paused at the second frame, t: its truth on the right.
    std::ofstream(dir.file("truth.txt")) << "2 space\n2 t\n";
    r = run(view + "--method none --script '" + dir.file("truth.txt") + "' --screenshot '" +
                dir.file("truth.png") + "'",
            dir, xvfb);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const Image truthShot = readImage(dir.file("truth.png"));
    EXPECT_LE(largestStep(truthShot, readImage(dir.file("r/frame_0001.png")), 0, 47), 1);
    EXPECT_LE(largestStep(truthShot, readImage(dir.file("r/truth_0001.png")), 49, 96), 1);
    EXPECT_GT(
        largestStep(readImage(dir.file("r/truth_0001.png")), readImage(dir.file("r/frame_0001.png")), 49, 96),
        8);
    // The temporal network's GPU form, its history on the GPU, against dejag filter (ungated, float32).
    r = run("filter --method cnn-temporal --gate off --precision fp32 --quiet '" + dir.file("r") + "' '" +
                dir.file("temporal") + "'",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    r = run(view + "--method cnn-temporal --device gpu --screenshot '" + dir.file("temporal.png") + "'", dir,
            xvfb);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_LE(largestStep(readImage(dir.file("temporal.png")), readImage(dir.file("temporal/frame_0002.png")),
                          0, 96),
              1);
    expectOneLineError(run(view + "--device fast", dir, xvfb), "--device");
    // The text overlay (on by default): drawn in the top left corner, nowhere else.
    for (const char* overlay : {"", "--no-overlay "}) {
        r = run(std::string("view --scene pipe --size 320x180 --frames 2 --method none ") + overlay +
                    "--screenshot '" + dir.file(*overlay ? "plain.png" : "overlay.png") + "'",
                dir, xvfb);
        ASSERT_EQ(r.exitCode, 0) << r.err;
    }
    const Image withText = readImage(dir.file("overlay.png")), plain = readImage(dir.file("plain.png"));
    int inside = 0, outside = 0;
    for (int y = 0; y < 180; ++y)
        for (int x = 0; x < 320; ++x) {
            bool differs = false;
            for (int c = 0; c < 3; ++c) differs = differs || withText.at(x, y, c) != plain.at(x, y, c);
            (x < 240 && y < 120 ? inside : outside) += differs;
        }
    EXPECT_GT(inside, 500);
    EXPECT_EQ(outside, 0);
}

TEST(Cli, FilterRunsFoldersSequencesAndChainsKeepingBitDepthAndAlpha) {
    testing::TempDir dir;
    const std::string model = writeTinyModel(dir.file("tiny.safetensors"), 2);
    // Three 16-bit RGBA frames of a hard diagonal edge, numbered from 1.
    std::filesystem::create_directories(dir.file("in"));
    for (int i = 1; i <= 3; ++i) {
        Image frame(40, 30, {"R", "G", "B", "A"}, PixelType::UInt16);
        for (int y = 0; y < 30; ++y)
            for (int x = 0; x < 40; ++x) {
                const bool inside = x + i > y;
                for (int c = 0; c < 3; ++c) frame.at(x, y, c) = inside ? 0.9f : 0.1f;
                frame.at(x, y, 3) = float(x) / 39.0f;
            }
        char name[64];
        std::snprintf(name, sizeof name, "in/frame_%04d.png", i);
        writeImage(dir.file(name), frame);
    }
    RunResult r = run("filter --chain fxaa,cnn --model '" + model + "' --json '" +
                          dir.file("in/frame_%04d.png") + "' '" + dir.file("out/f_%02d.png") + "'",
                      dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    nlohmann::json j = nlohmann::json::parse(r.out);
    ASSERT_EQ(j["frames"].size(), 3u);
    EXPECT_EQ(j["frames"][0]["stages"].size(), 2u);
    EXPECT_EQ(j["frames"][0]["stages"][1]["method"], "cnn");
    for (int i = 1; i <= 3; ++i) {
        char name[64];
        std::snprintf(name, sizeof name, "out/f_%02d.png", i);
        const Image out = readImage(dir.file(name));
        char inName[64];
        std::snprintf(inName, sizeof inName, "in/frame_%04d.png", i);
        const Image in = readImage(dir.file(inName));
        EXPECT_EQ(out.storage, PixelType::UInt16);
        ASSERT_EQ(out.channels(), 4);
        for (int x = 0; x < 40; ++x) EXPECT_EQ(out.at(x, 5, 3), in.at(x, 5, 3)) << "alpha untouched";
    }
    // A folder in, a folder out, with the same names; the CNN alone, gated.
    r = run("filter --method cnn --model '" + model + "' --gate 0.01 --json --quiet '" + dir.file("in") +
                "' '" + dir.file("folder-out") + "'",
            dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_TRUE(std::filesystem::exists(dir.file("folder-out/frame_0002.png")));
    // Bad chains and sequences are one line.
    expectOneLineError(run("filter --chain fxaa,taa '" + dir.file("in") + "' '" + dir.file("o") + "'", dir),
                       "depth.Z");
    expectOneLineError(
        run("filter --method fxaa --chain fxaa '" + dir.file("in") + "' '" + dir.file("o") + "'", dir),
        "--method");
    expectOneLineError(
        run("filter --method fxaa '" + dir.file("in/x_%04d.png") + "' '" + dir.file("o_%04d.png") + "'", dir),
        "no frame");
    expectOneLineError(
        run("filter --method fxaa '" + dir.file("in/frame_%04d.png") + "' '" + dir.file("o.png") + "'", dir),
        "pattern");
}

// Sequences are read one frame ahead and written one behind on their own threads: the outputs equal
// frame-by-frame runs, and a frame that cannot be read stops the run with every earlier frame written
// whole and nothing of the later ones.
TEST(Cli, FilterSequenceOverlapsFileIoAndStopsAtAnUnreadableFrame) {
    testing::TempDir dir;
    const std::string model = writeTinyModel(dir.file("tiny.safetensors"), 2);
    std::filesystem::create_directories(dir.file("in"));
    for (int i = 0; i < 5; ++i) {
        Image frame(48, 20, {"R", "G", "B"}, PixelType::Float);  // linear light: encoded for the filters
        for (int y = 0; y < 20; ++y)
            for (int x = 0; x < 48; ++x)
                for (int c = 0; c < 3; ++c) frame.at(x, y, c) = (x + 2 * i > y + c) ? 0.8f : 0.02f;
        writeImage(dir.file("in/f_" + std::to_string(i) + ".exr"), frame);
    }
    RunResult r = run("filter --chain fxaa,cnn --model '" + model + "' --json '" + dir.file("in/f_%d.exr") +
                          "' '" + dir.file("out/f_%d.exr") + "'",
                      dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(nlohmann::json::parse(r.out)["frames"].size(), 5u);
    for (int i = 0; i < 5; ++i) {
        const std::string n = std::to_string(i);
        r = run("filter --chain fxaa,cnn --model '" + model + "' --quiet '" + dir.file("in/f_" + n + ".exr") +
                    "' '" + dir.file("single_" + n + ".exr") + "'",
                dir);
        ASSERT_EQ(r.exitCode, 0) << r.err;
        EXPECT_EQ(readImage(dir.file("out/f_" + n + ".exr")).pixels,
                  readImage(dir.file("single_" + n + ".exr")).pixels)
            << "frame " << i;
    }
    // Frame 2 truncated: frames 0 and 1 are written, 2 to 4 are not.
    const std::string bad = dir.file("in/f_2.exr");
    std::filesystem::resize_file(bad, std::filesystem::file_size(bad) / 2);
    r = run("filter --method cnn --model '" + model + "' --quiet '" + dir.file("in/f_%d.exr") + "' '" +
                dir.file("stopped/f_%d.exr") + "'",
            dir);
    expectOneLineError(r, "f_2.exr");
    EXPECT_EQ(readImage(dir.file("stopped/f_1.exr")).width, 48);
    EXPECT_TRUE(std::filesystem::exists(dir.file("stopped/f_0.exr")));
    EXPECT_EQ(filesIn(dir.file("stopped")), 2u) << "only frames 0 and 1, and no temporary file";
}

}  // namespace
}  // namespace dejag
