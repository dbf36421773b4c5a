// What a careless or hostile user does to dejag, one test per case of docs/bad-input.md's "Reliability"
// rows: a full disk, a model of the wrong shape or with unusable weights, a NaN in validation, two
// processes on one folder, a killed parent, an interrupted write, mixed colour spaces, and numbers that are
// not numbers. Each case ends in one error line and exit 2, with nothing already written lost.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>

#include "base/error.h"
#include "base/files.h"
#include "data/evaluation.h"
#include "data/image.h"
#include "nn/model.h"
#include "nn/safetensors.h"
#include "tests/cli/cli_util.h"
#include "tests/test_util.h"

namespace dejag {
namespace {

namespace fs = std::filesystem;

// An 8-bit RGB noise image: its PNG, JPEG, TIFF and EXR files are all far above a few kilobytes.
Image noiseImage(int width, int height, unsigned seed) {
    Image image(width, height, {"R", "G", "B"}, PixelType::UInt8);
    std::mt19937 random(seed);
    for (float& v : image.pixels) v = float(random() % 256) / 255.0f;
    return image;
}

// The names in a folder that dejag gives its temporary files.
std::vector<std::string> temporaryFilesIn(const fs::path& folder) {
    std::vector<std::string> found;
    for (const auto& entry : fs::recursive_directory_iterator(folder))
        if (isTemporaryFileName(entry.path().filename().string())) found.push_back(entry.path().string());
    return found;
}

// A process-wide file-size limit (what a full disk looks like to write(): it fails, here with EFBIG), for
// the rest of a test. SIGXFSZ is ignored as installTemporaryFileCleanup() makes the binary ignore it.
class FileSizeLimit {
  public:
    explicit FileSizeLimit(rlim_t bytes) {
        ::getrlimit(RLIMIT_FSIZE, &saved_);
        previous_ = ::signal(SIGXFSZ, SIG_IGN);
        rlimit limit = saved_;
        limit.rlim_cur = bytes;
        ::setrlimit(RLIMIT_FSIZE, &limit);
    }
    ~FileSizeLimit() {
        ::setrlimit(RLIMIT_FSIZE, &saved_);
        ::signal(SIGXFSZ, previous_);
    }

  private:
    rlimit saved_{};
    sighandler_t previous_ = SIG_DFL;
};

// A pid that no process has: a child that has exited and been reaped.
pid_t deadPid() {
    const pid_t pid = ::fork();
    if (pid == 0) _exit(0);
    ::waitpid(pid, nullptr, 0);
    return pid;
}

// A small dataset for the training cases (seconds to render).
std::string tinyDataset(const testing::TempDir& dir) {
    const std::string data = dir.file("data");
    const RunResult r =
        run("data generate --families shapes,pipes,foliage --test-families foliage --count 30 "
            "--size 64x64 --truth 4 --quiet --out '" +
                data + "'",
            dir);
    EXPECT_EQ(r.exitCode, 0) << r.err;
    return data;
}

void writeText(const std::string& path, const std::string& text) {
    std::ofstream(path) << text;
}

// A model file of the given architecture, its weights initialised and then scaled.
void saveModelOf(const std::string& path, const nlohmann::json& architecture, float weightScale = 1.0f) {
    nn::Model model = nn::Model::fromArchitecture(architecture);
    model.initialize(1);
    for (int64_t i = 0; i < model.parameterCount(); ++i) model.parameterData()[i] *= weightScale;
    nn::saveModel(path, model);
}

nlohmann::json convThen(const nlohmann::json& last) {
    nlohmann::json nodes = nlohmann::json::array();
    nodes.push_back({{"name", "c"},
                     {"op", "conv2d"},
                     {"inputs", {"input"}},
                     {"out_channels", 3},
                     {"kernel", 3},
                     {"padding", "same"}});
    if (!last.is_null()) nodes.push_back(last);
    return {{"name", "shape-test"}, {"input_channels", 3}, {"nodes", nodes}};
}

// ---- 1. A full disk -----------------------------------------------------------------------------------

TEST(Reliability, AFailedWriteOfEveryFormatNamesTheReasonAndKeepsTheEarlierFile) {
    testing::TempDir dir;
    for (const char* extension : {"png", "jpg", "tif", "exr", "safetensors", "json"}) {
        SCOPED_TRACE(extension);
        const std::string path = dir.file(std::string("out.") + extension);
        const auto write = [&](unsigned seed) {
            const std::string ext = extension;
            if (ext == "safetensors") {
                std::vector<float> values(20000, float(seed));
                nn::writeSafetensors(path, {{"w", {20000}, values.data()}}, {});
            } else if (ext == "json") {
                writeTextFileAtomically(path, std::string(50000, char('a' + seed)));
            } else {
                writeImage(path, noiseImage(256, 256, seed));
            }
        };
        write(1);
        const std::string before = testing::slurp(path);
        ASSERT_GT(before.size(), 16384u);
        try {
            const FileSizeLimit limit(8192);
            write(2);
            ADD_FAILURE() << "a write past the file-size limit succeeded";
        } catch (const Error& error) {
            EXPECT_NE(std::string(error.what()).find("File too large"), std::string::npos) << error.what();
            EXPECT_NE(std::string(error.what()).find(path), std::string::npos) << error.what();
        }
        EXPECT_TRUE(testing::slurp(path) == before) << "the earlier file changed";
        EXPECT_TRUE(temporaryFilesIn(dir.path()).empty());
    }
}

TEST(Reliability, FilterSequenceAndSsimMapOnAFullDiskExitTwoAndLeaveNothingBehind) {
    testing::TempDir dir;
    fs::create_directories(dir.path() / "in");
    fs::create_directories(dir.path() / "out");
    for (int i = 0; i < 3; ++i) {
        char name[32];
        std::snprintf(name, sizeof name, "in/f_%04d.png", i);
        writeImage(dir.file(name), noiseImage(256, 256, unsigned(i)));
    }
    // The earlier output of a good run stays as it was.
    ASSERT_EQ(run("filter --method fxaa --quiet '" + dir.file("in/f_0000.png") + "' '" +
                      dir.file("out/one.png") + "'",
                  dir)
                  .exitCode,
              0);
    const std::string good = testing::slurp(dir.file("out/one.png"));
    const std::string limited = "ulimit -f 64;";  // 32 or 64 KB, whatever the shell's block: below a frame
    expectOneLineError(run("filter --method fxaa --force '" + dir.file("in/f_0000.png") + "' '" +
                               dir.file("out/one.png") + "'",
                           dir, limited),
                       "File too large");
    EXPECT_TRUE(testing::slurp(dir.file("out/one.png")) == good);
    expectOneLineError(run("filter --method fxaa --quiet '" + dir.file("in/f_%04d.png") + "' '" +
                               dir.file("out/g_%04d.png") + "'",
                           dir, limited),
                       "File too large");
    EXPECT_FALSE(fs::exists(dir.file("out/g_0000.png"))) << "a frame was written past a full disk";
    const RunResult map = run("metrics --ssim-map '" + dir.file("out/map.png") + "' '" +
                                  dir.file("in/f_0000.png") + "' '" + dir.file("in/f_0001.png") + "'",
                              dir, limited);
    EXPECT_EQ(map.exitCode, 2) << map.err;
    EXPECT_NE(map.err.find("File too large"), std::string::npos) << map.err;
    EXPECT_FALSE(fs::exists(dir.file("out/map.png")));
    EXPECT_TRUE(temporaryFilesIn(dir.path()).empty());
}

// The real thing where the machine allows it (root, a mount namespace that may mount): a 1 MB tmpfs.
TEST(Reliability, AFullTmpfsIsNoSpaceLeftAndTheEarlierFileSurvives) {
    testing::TempDir dir;
    const std::string disk = dir.file("disk");
    fs::create_directories(disk);
    if (::geteuid() != 0 || ::mount("tmpfs", disk.c_str(), "tmpfs", 0, "size=1m") != 0)
        GTEST_SKIP() << "cannot mount a tmpfs here; the file-size-limit tests cover the same path";
    struct Unmount {
        std::string path;
        ~Unmount() { ::umount2(path.c_str(), MNT_DETACH); }
    } unmount{disk};
    writeImage(dir.file("in.png"), noiseImage(256, 256, 7));
    const std::string out = disk + "/out.png";
    ASSERT_EQ(run("filter --method fxaa --quiet '" + dir.file("in.png") + "' '" + out + "'", dir).exitCode,
              0);
    const std::string good = testing::slurp(out);
    {
        std::ofstream fill(disk + "/fill", std::ios::binary);
        const std::string block(4096, 'x');
        while (fill.write(block.data(), block.size())) {
        }
    }
    expectOneLineError(run("filter --method fxaa --force '" + dir.file("in.png") + "' '" + out + "'", dir),
                       "No space left on device");
    EXPECT_TRUE(testing::slurp(out) == good) << "the earlier output was lost";
    EXPECT_TRUE(temporaryFilesIn(disk).empty());
}

// ---- 2. A model whose output size is not its input's --------------------------------------------------

TEST(Reliability, AModelThatChangesTheFrameSizeIsRefusedWhenItLoads) {
    testing::TempDir dir;
    writeImage(dir.file("in.png"), noiseImage(64, 64, 3));
    const std::vector<std::pair<std::string, nlohmann::json>> shapes = {
        {"2x", {{"name", "u"}, {"op", "upsample"}, {"inputs", {"c"}}, {"factor", 2}}},
        {"8x", {{"name", "u"}, {"op", "upsample"}, {"inputs", {"c"}}, {"factor", 8}}},
        {"half", {{"name", "p"}, {"op", "maxpool2d"}, {"inputs", {"c"}}, {"kernel", 2}}}};
    for (const auto& [name, last] : shapes) {
        SCOPED_TRACE(name);
        const std::string model = dir.file(name + ".safetensors");
        saveModelOf(model, convThen(last));
        expectOneLineError(run("filter --method cnn --model '" + model + "' '" + dir.file("in.png") + "' '" +
                                   dir.file("out.png") + "'",
                               dir),
                           "returns the size it is given");
        EXPECT_FALSE(fs::exists(dir.file("out.png")));
    }
    // Training refuses it before it makes its run folder (it used to crash in the SSIM loss).
    writeText(dir.file("up.json"), convThen(shapes[0].second).dump());
    expectOneLineError(run("train --data '" + dir.file("nodata") + "' --out '" + dir.file("run") +
                               "' --arch '" + dir.file("up.json") + "' --steps 2 --patch 32",
                           dir),
                       "returns the size it is given");
    EXPECT_FALSE(fs::exists(dir.file("run")));
}

// ---- 3. Non-finite outputs ------------------------------------------------------------------------------

TEST(Reliability, ANonFiniteOutputScoresTheWorstNotAPerfectPsnr) {
    data::EvaluationItem item;
    item.id = "x";
    item.truth = noiseImage(32, 32, 1);
    item.truth.storage = PixelType::Float;
    item.hasRegion[0] = true;
    Image output = item.truth;
    output.pixels[100] = NAN;
    const data::ImageScore score = data::scoreImage(item, output);
    EXPECT_TRUE(score.nonFinite);
    EXPECT_EQ(score.region[0].psnr, data::kWorstPsnr);
    EXPECT_EQ(score.region[0].ssim, -1.0);
    data::ScoreSummary summary;
    summary.add(score);
    summary.finish();
    EXPECT_EQ(summary.nonFiniteImages, 1);
    EXPECT_EQ(summary.psnr[0], data::kWorstPsnr);
}

TEST(Reliability, TrainingNeverSavesANonFiniteModelAsBestAndTheFilterRefusesHugeWeights) {
    testing::TempDir dir;
    const std::string data = tinyDataset(dir);
    nlohmann::json residual = convThen({{"name", "out"}, {"op", "add"}, {"inputs", {"input", "c"}}});
    residual["output"] = "out";
    // Two layers of weights 1e30 times too large: the first validation's output is NaN (the infinities of
    // the first layer meet zeros in the second).
    nlohmann::json huge = residual;
    huge["nodes"][0]["out_channels"] = 8;
    huge["nodes"][0]["activation"] = "relu";
    huge["nodes"][0]["init_scale"] = 1e30;
    const nlohmann::json second = {{"name", "c2"},      {"op", "conv2d"}, {"inputs", {"c"}},
                                   {"out_channels", 3}, {"kernel", 3},    {"padding", "same"},
                                   {"init_scale", 1e30}};
    huge["nodes"].insert(huge["nodes"].begin() + 1, second);
    huge["nodes"][2]["inputs"] = {"input", "c2"};
    writeText(dir.file("huge.json"), huge.dump());
    const RunResult r =
        run("train --data '" + data + "' --out '" + dir.file("run") + "' --arch '" + dir.file("huge.json") +
                "' --steps 6 --batch 2 --patch 32 --eval-every 3 --quiet",
            dir);
    EXPECT_NE(r.err.find("never kept as the best model"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("run/best.safetensors"))) << "a non-finite model was saved as the best";
    EXPECT_EQ(r.out.find("100.00 dB"), std::string::npos) << r.out;
    // The same weights as a model file: refused when it loads, before any frame.
    writeImage(dir.file("in.png"), noiseImage(64, 64, 3));
    for (const float scale : {1e30f, 1e38f}) {
        saveModelOf(dir.file("huge.safetensors"), residual, scale);
        expectOneLineError(run("filter --method cnn --model '" + dir.file("huge.safetensors") + "' '" +
                                   dir.file("in.png") + "' '" + dir.file("out.png") + "'",
                               dir),
                           "unusable");
        EXPECT_FALSE(fs::exists(dir.file("out.png")));
    }
}

// ---- 4. Two processes on one folder ---------------------------------------------------------------------

TEST(Reliability, ASecondProcessOnARunOrDatasetFolderIsRefused) {
    testing::TempDir dir;
    const std::string data = tinyDataset(dir);
    {
        const FolderLock held(dir.file("data"), "a dataset generation");
        EXPECT_THROW(FolderLock(dir.file("data"), "a dataset generation"), Error);
        expectOneLineError(
            run("data generate --families shapes,pipes,foliage --test-families foliage --count 30 "
                "--size 64x64 --truth 4 --out '" +
                    data + "'",
                dir),
            "in use by a dataset generation of another dejag process");
    }
    fs::create_directories(dir.file("run"));
    {
        const FolderLock held(dir.file("run"), "a training run");
        expectOneLineError(
            run("train --data '" + data + "' --out '" + dir.file("run") + "' --steps 2 --patch 32", dir),
            "in use by a training run");
        EXPECT_FALSE(fs::exists(dir.file("run/run.json"))) << "the refused run wrote into the folder";
    }
    // Released with its holder: the same command now runs.
    const RunResult r = run("train --data '" + data + "' --out '" + dir.file("run") +
                                "' --steps 2 --batch 2 --patch 32 --eval-every 2 --quiet",
                            dir);
    EXPECT_EQ(r.exitCode, 0) << r.err;
}

// ---- 5. Workers end with their parent ---------------------------------------------------------------------

std::vector<pid_t> childrenOf(pid_t parent) {
    std::vector<pid_t> children;
    for (const auto& entry : fs::directory_iterator("/proc")) {
        const std::string name = entry.path().filename().string();
        if (name.find_first_not_of("0123456789") != std::string::npos) continue;
        std::ifstream stat(entry.path() / "stat");
        std::string line;
        std::getline(stat, line);
        const size_t close = line.rfind(')');
        if (close == std::string::npos) continue;
        std::istringstream rest(line.substr(close + 2));
        char state;
        pid_t ppid;
        rest >> state >> ppid;
        if (ppid == parent && state != 'Z') children.push_back(pid_t(std::stol(name)));
    }
    return children;
}

bool running(pid_t pid) {
    std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
    std::string line;
    if (!std::getline(stat, line)) return false;
    const size_t close = line.rfind(')');
    return close != std::string::npos && line.size() > close + 2 && line[close + 2] != 'Z' &&
           line[close + 2] != 'X';
}

TEST(Reliability, DatasetWorkersEndWithTheirParentWhateverEndsIt) {
    for (const int signal : {SIGKILL, SIGTERM}) {
        SCOPED_TRACE(signal == SIGKILL ? "SIGKILL" : "SIGTERM");
        testing::TempDir dir;
        const std::string data = dir.file("data");
        const pid_t parent = ::fork();
        if (parent == 0) {
            ::execl(DEJAG_BINARY, DEJAG_BINARY, "data", "generate", "--families", "shapes", "--test-families",
                    "none", "--count", "200", "--size", "256x256", "--truth", "64", "--workers", "2",
                    "--quiet", "--out", data.c_str(), static_cast<char*>(nullptr));
            _exit(127);
        }
        std::vector<pid_t> workers;
        for (int wait = 0; wait < 200 && workers.size() < 2; ++wait) {
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
            workers = childrenOf(parent);
        }
        ASSERT_EQ(workers.size(), 2u) << "the workers did not start";
        ::kill(parent, signal);
        int status = 0;
        ::waitpid(parent, &status, 0);
        EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == signal);
        bool gone = false;
        for (int wait = 0; wait < 100 && !gone; ++wait) {
            gone = std::none_of(workers.begin(), workers.end(), running);
            if (!gone) std::this_thread::sleep_for(std::chrono::milliseconds(50));
        }
        EXPECT_TRUE(gone) << "a worker outlived its parent by 5 s";
        if (!gone)
            for (pid_t w : workers) ::kill(w, SIGKILL);
        EXPECT_TRUE(temporaryFilesIn(data).empty());
    }
}

// ---- 6. Temporary files of interrupted writes -------------------------------------------------------------

TEST(Reliability, ASignalRemovesTheTemporaryFilesOfWritesInProgress) {
    for (const int signal : {SIGINT, SIGTERM, SIGHUP}) {
        testing::TempDir dir;
        const pid_t child = ::fork();
        if (child == 0) {
            installTemporaryFileCleanup();
            AtomicFile file(dir.file("frame.exr"));
            file.write("partial");
            ::raise(signal);
            _exit(0);  // not reached
        }
        int status = 0;
        ::waitpid(child, &status, 0);
        EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == signal)
            << "the signal no longer ends the process";
        EXPECT_EQ(filesIn(dir.path()), 0u) << "a temporary file survived signal " << signal;
    }
}

TEST(Reliability, TemporaryFilesOfDeadProcessesAreNeitherFramesNorKept) {
    testing::TempDir dir;
    fs::create_directories(dir.path() / "in");
    fs::create_directories(dir.path() / "out");
    writeImage(dir.file("in/a.png"), noiseImage(32, 32, 1));
    const std::string dead = std::to_string(deadPid());
    // What a kill -9 in the middle of a write leaves: a partial file under a hidden temporary name.
    writeText(dir.file("in/.b.tmp-" + dead + "-0.png"), "partial");
    writeText(dir.file("out/.a.tmp-" + dead + "-3.png"), "partial");
    const std::string alive = dir.file("out/.c.tmp-" + std::to_string(::getpid()) + "-0.png");
    writeText(alive, "a write of a running process");
    const RunResult r =
        run("filter --method fxaa --quiet '" + dir.file("in") + "' '" + dir.file("out") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_TRUE(fs::exists(dir.file("out/a.png")));
    EXPECT_FALSE(fs::exists(dir.file("out/.b.tmp-" + dead + "-0.png")))
        << "a temporary file was read as a frame";
    EXPECT_FALSE(fs::exists(dir.file("out/.a.tmp-" + dead + "-3.png"))) << "a dead process's file was kept";
    EXPECT_TRUE(fs::exists(alive)) << "a running process's file was removed";
    EXPECT_TRUE(isTemporaryFileName(".frame_0001.tmp-123-4.exr"));
    EXPECT_FALSE(isTemporaryFileName("frame_0001.exr"));
    EXPECT_FALSE(isTemporaryFileName(".tmp-1-2.exr"));
}

// ---- 7. Colour space follows the file ---------------------------------------------------------------------

TEST(Reliability, ColourSpaceFollowsTheFileThroughFilterAndMetrics) {
    testing::TempDir dir;
    ASSERT_EQ(run("render --scene pipe --size 64x64 --quiet --out '" + dir.file("r") + "'", dir).exitCode, 0);
    const std::string exr = dir.file("r/frame_0000.exr"), png = dir.file("r/frame_0000.png");
    ASSERT_EQ(run("filter --method fxaa --quiet '" + exr + "' '" + dir.file("o.png") + "'", dir).exitCode, 0);
    ASSERT_EQ(run("filter --method fxaa --quiet '" + exr + "' '" + dir.file("o.exr") + "'", dir).exitCode, 0);
    const Image encoded = readImage(dir.file("o.png")), linear = readImage(dir.file("o.exr"));
    ASSERT_EQ(encoded.pixelCount(), linear.pixelCount());
    double largest = 0;
    for (size_t p = 0; p < linear.pixelCount(); ++p)
        for (int c = 0; c < 3; ++c) {
            const float expected = std::clamp(
                linearToSrgb(std::max(linear.pixels[p * size_t(linear.channels()) + size_t(c)], 0.0f)), 0.0f,
                1.0f);
            largest = std::max(
                largest,
                double(std::abs(encoded.pixels[p * size_t(encoded.channels()) + size_t(c)] - expected)));
        }
    EXPECT_LT(largest, 1.0 / 60000) << "the PNG does not hold the sRGB encoding of the EXR's linear light";
    expectOneLineError(run("metrics '" + png + "' '" + exr + "'", dir), "--space");
    const RunResult srgb = run("metrics --json --space srgb '" + png + "' '" + exr + "'", dir);
    ASSERT_EQ(srgb.exitCode, 0) << srgb.err;
    EXPECT_GT(nlohmann::json::parse(srgb.out)["psnr"].get<double>(), 45.0) << "one frame in two files";
    const RunResult lin = run("metrics --json --space linear '" + png + "' '" + exr + "'", dir);
    ASSERT_EQ(lin.exitCode, 0) << lin.err;
    EXPECT_EQ(nlohmann::json::parse(lin.out)["space"], "linear");
    EXPECT_GT(nlohmann::json::parse(lin.out)["psnr"].get<double>(), 40.0);
}

// ---- 8. Bad input that used to be an internal error or silently accepted -------------------------------

TEST(Reliability, BadNumbersSizesAndPatternsAreOneLine) {
    testing::TempDir dir;
    const std::string data = tinyDataset(dir);
    const std::string train =
        "train --data '" + data + "' --out '" + dir.file("run") + "' --steps 2 --patch 32 ";
    expectOneLineError(run(train + "--arch kpn:100000x3", dir), "width");
    nlohmann::json giant = convThen(nullptr);
    giant["nodes"][0]["out_channels"] = 1000000000;
    writeText(dir.file("giant.json"), giant.dump());
    expectOneLineError(run(train + "--arch '" + dir.file("giant.json") + "'", dir), "out_channels");
    expectOneLineError(run(train + "--clip nan", dir), "--clip");
    expectOneLineError(run(train + "--epochs inf", dir), "--epochs");
    expectOneLineError(run(train + "--lr nan", dir), "--lr");
    expectOneLineError(run(train + "--seed -1", dir), "--seed");
    // Out of range, found by sweeping every numeric flag of every subcommand with -1, 0, +-2^31, +-1e30.
    expectOneLineError(run(train + "--batch 2147483647", dir), "--batch");  // was std::bad_alloc in a thread
    for (const char* flag : {"--warmup", "--clip", "--val-images", "--patience"})
        expectOneLineError(run(train + flag + " -1", dir), flag);
    for (const std::string flag :
         {"--jitter-spread -1", "--tolerance -1", "--pixel-tolerance 0", "--truth 2147483647"})
        expectOneLineError(run("render --scene pipe --size 8x8 --out '" + dir.file("r") + "' " + flag, dir),
                           flag.substr(0, flag.find(' ')));
    expectOneLineError(
        run("filter --method cnn --tile -1 '" + dir.file("a.png") + "' '" + dir.file("b.png") + "'", dir),
        "--tile");
    expectOneLineError(
        run("render --scene pipe --size 8x8 --start 2147483646 --frames 3 --out '" + dir.file("r") + "'",
            dir),
        "--start");
    EXPECT_FALSE(fs::exists(dir.file("r")));
    writeImage(dir.file("a.png"), noiseImage(16, 16, 1));
    expectOneLineError(
        run("metrics --data-range nan '" + dir.file("a.png") + "' '" + dir.file("a.png") + "'", dir),
        "--data-range");
    const RunResult zero =
        run("metrics --data-range 0 '" + dir.file("a.png") + "' '" + dir.file("a.png") + "'", dir);
    expectOneLineError(zero, "--data-range");
    EXPECT_LT(zero.err.size(), 120u) << zero.err;
    expectOneLineError(
        run("filter --chain fxaa, '" + dir.file("a.png") + "' '" + dir.file("b.png") + "'", dir), "--chain");
    expectOneLineError(
        run("filter --method fxaa '" + dir.file("f_%999999999d.png") + "' '" + dir.file("o_%d.png") + "'",
            dir),
        "pattern");
    // A gap in a sequence: refused, naming the missing frame, instead of dropping every frame after it.
    for (int i : {0, 1, 2, 4, 5})
        writeImage(dir.file("s_" + std::to_string(i) + ".png"), noiseImage(16, 16, unsigned(i)));
    expectOneLineError(
        run("filter --method fxaa '" + dir.file("s_%d.png") + "' '" + dir.file("t_%d.png") + "'", dir),
        "frame 3 is missing");
    EXPECT_FALSE(fs::exists(dir.file("t_0.png")));
    // A truncated dataset.json is named, not a JSON library's exception.
    fs::copy(data, dir.file("cut"), fs::copy_options::recursive);
    fs::resize_file(dir.file("cut/dataset.json"), 20);
    expectOneLineError(
        run("train --data '" + dir.file("cut") + "' --out '" + dir.file("run2") + "' --steps 2 --patch 32",
            dir),
        "dataset.json' is corrupt");
}

// ---- 9. Messages
// -------------------------------------------------------------------------------------------

TEST(Reliability, MessagesNameTheReasonAndAFailedRunLeavesNoFolder) {
    testing::TempDir dir;
    const std::string data = tinyDataset(dir);
    // A run that fails before it starts leaves no empty folder behind.
    expectOneLineError(
        run("train --data '" + dir.file("missing") + "' --out '" + dir.file("run") + "' --steps 2 --patch 32",
            dir),
        "missing");
    EXPECT_FALSE(fs::exists(dir.file("run")));
    // A checkpoint is not a model: the message says what to do.
    ASSERT_EQ(run("train --data '" + data + "' --out '" + dir.file("run") +
                      "' --arch kpn:4x2 --steps 2 --batch 2 --patch 32 --eval-every 2 --quiet",
                  dir)
                  .exitCode,
              0);
    writeImage(dir.file("a.png"), noiseImage(32, 32, 1));
    expectOneLineError(run("filter --method cnn --model '" + dir.file("run/checkpoint.safetensors") + "' '" +
                               dir.file("a.png") + "' '" + dir.file("b.png") + "'",
                           dir),
                       "train export");
    // DEJAG_THREADS=0 means the default, as documented.
    const RunResult threads =
        run("metrics '" + dir.file("a.png") + "' '" + dir.file("a.png") + "'", dir, "DEJAG_THREADS=0");
    EXPECT_EQ(threads.exitCode, 0) << threads.err;
    // The documented side limit: 65,536 pixels.
    writeImage(dir.file("wide.png"), Image(65537, 1, {"Y"}, PixelType::UInt8));
    expectOneLineError(run("metrics '" + dir.file("wide.png") + "' '" + dir.file("wide.png") + "'", dir),
                       "larger than dejag accepts");
}

}  // namespace
}  // namespace dejag
