// Datasets: item plans and splits, generation through the binary (worker processes), resume after
// kill -9, verify and stats, bad input.
#include "data/dataset.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include "base/error.h"
#include "data/image.h"
#include "tests/test_util.h"

namespace dejag::data {
namespace {

namespace fs = std::filesystem;

DatasetSpec allFamilies(int count) {
    DatasetSpec spec;
    for (const FamilyInfo& f : datasetFamilies()) spec.families.push_back(f.name);
    spec.testFamilies = defaultTestFamilies();
    spec.count = count;
    return spec;
}

TEST(DatasetPlan, FamiliesRoundRobinAndTestFamiliesNeverLeak) {
    const DatasetSpec spec = allFamilies(2000);
    std::set<std::string> trainFamilies, testFamilies;
    int validation = 0, nonTest = 0;
    for (int i = 0; i < spec.count; ++i) {
        const ItemPlan p = planItem(spec, i);
        EXPECT_EQ(p.family, spec.families[size_t(i) % spec.families.size()]);
        if (p.split == Split::Test) {
            testFamilies.insert(p.family);
        } else {
            trainFamilies.insert(p.family);
            ++nonTest;
            validation += p.split == Split::Validation;
        }
        const ItemPlan again = planItem(spec, i);
        EXPECT_EQ(again.seed, p.seed);
        EXPECT_EQ(again.scene, p.scene);
    }
    EXPECT_EQ(testFamilies, (std::set<std::string>(spec.testFamilies.begin(), spec.testFamilies.end())));
    for (const std::string& f : testFamilies) EXPECT_FALSE(trainFamilies.count(f)) << f;
    EXPECT_NEAR(double(validation) / nonTest, 0.1, 0.03);
}

TEST(DatasetPlan, RefusesBadSpecs) {
    DatasetSpec spec = allFamilies(10);
    spec.families.push_back("teapots");
    EXPECT_THROW(spec.validate(), Error);
    spec = allFamilies(0);
    EXPECT_THROW(spec.validate(), Error);
    spec = allFamilies(10);
    spec.testFamilies = {"nowhere"};
    EXPECT_THROW(spec.validate(), Error);
    spec = allFamilies(10);
    spec.testFamilies = spec.families;
    EXPECT_THROW(spec.validate(), Error);
    EXPECT_NO_THROW(allFamilies(10).validate());
    EXPECT_EQ(DatasetSpec::fromJson(allFamilies(7).toJson()).toJson(), allFamilies(7).toJson());
    // A dataset.json is checked like a command line (found by fuzz/fuzz_manifest.cpp: an empty family
    // list divided by zero when `data verify` planned the items).
    nlohmann::json noFamilies = allFamilies(7).toJson();
    noFamilies["families"] = nlohmann::json::array();
    noFamilies["test_families"] = nlohmann::json::array();
    EXPECT_THROW((void)DatasetSpec::fromJson(noFamilies), Error);
}

// ---- Through the binary -------------------------------------------------------------------------------

int run(const std::string& arguments, std::string* err = nullptr, std::string* out = nullptr) {
    const std::string base = fs::temp_directory_path() / ("dejag-data-" + std::to_string(::getpid()));
    const std::string errFile = base + "-err", outFile = base + "-out";
    const std::string command = "'" + std::string(DEJAG_BINARY) + "' " + arguments + " >" +
                                (out ? "'" + outFile + "'" : std::string("/dev/null")) + " 2>'" + errFile +
                                "'";
    const int status = std::system(command.c_str());
    if (err) *err = testing::slurp(errFile);
    if (out) *out = testing::slurp(outFile);
    fs::remove(errFile);
    fs::remove(outFile);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

using testing::contents;
using testing::expectSameFiles;
using testing::slurp;

const std::string kTiny =
    "data generate --families shapes,pipes,thin,foliage,random --test-families foliage "
    "--count 10 --size 48x48 --truth 8 --quiet";

TEST(DatasetGenerate, TinyRecipeVerifiesAndKeepsFamiliesApart) {
    testing::TempDir dir;
    const std::string out = dir.file("tiny");
    ASSERT_EQ(run(kTiny + " --workers 2 --out '" + out + "'"), 0);
    EXPECT_TRUE(verifyDataset(out).ok());
    const std::vector<nlohmann::json> records = readManifest(out);
    ASSERT_EQ(records.size(), 10u);
    std::set<std::string> train, test;
    for (size_t i = 0; i < records.size(); ++i) {
        EXPECT_EQ(records[i]["index"].get<int>(), int(i));  // sorted once complete
        (records[i]["split"] == "test" ? test : train).insert(records[i]["family"].get<std::string>());
    }
    EXPECT_EQ(test, std::set<std::string>{"foliage"});
    EXPECT_FALSE(train.count("foliage"));
    const nlohmann::json stats = datasetStats(out);
    EXPECT_EQ(stats["items"].get<int>(), 10);
    EXPECT_EQ(stats["families"]["foliage"]["splits"]["test"].get<int>(), 2);
    // Running the same command again renders nothing and changes nothing.
    const auto before = contents(out);
    ASSERT_EQ(run(kTiny + " --workers 2 --out '" + out + "'"), 0);
    EXPECT_TRUE(contents(out) == before);
}

// Close-ups: a share of the items get a narrower view at a random point of the full one, recorded in
// the manifest; a dataset without them describes itself as before (no "close_ups" key).
TEST(DatasetGenerate, CloseUpsNarrowTheViewOfTheSameItems) {
    DatasetSpec spec = allFamilies(5);
    EXPECT_FALSE(spec.toJson().contains("close_ups"));
    spec.closeUps = 0.3;
    EXPECT_EQ(DatasetSpec::fromJson(spec.toJson()).closeUps, 0.3);
    spec.closeUps = 1.5;
    EXPECT_THROW(spec.validate(), Error);
    testing::TempDir dir;
    const std::string recipe =
        "data generate --families shapes,pipes --test-families none --count 4 "
        "--size 48x48 --truth 8 --quiet --out '";
    ASSERT_EQ(run(recipe + dir.file("full") + "'"), 0);
    ASSERT_EQ(run(recipe + dir.file("close") + "' --close-ups 1"), 0);
    std::string err;
    EXPECT_EQ(run(recipe + dir.file("bad") + "' --close-ups -0.5", &err), 2);
    EXPECT_NE(err.find("--close-ups"), std::string::npos) << err;
    const std::vector<nlohmann::json> full = readManifest(dir.file("full")),
                                      close = readManifest(dir.file("close"));
    ASSERT_EQ(full.size(), 4u);
    ASSERT_EQ(close.size(), 4u);
    for (size_t i = 0; i < 4; ++i) {
        EXPECT_EQ(close[i]["scene"], full[i]["scene"]);
        EXPECT_FALSE(full[i].contains("close_up"));
        EXPECT_TRUE(close[i].value("close_up", false));
        const double ratio =
            full[i]["camera"]["fov_y"].get<double>() / close[i]["camera"]["fov_y"].get<double>();
        EXPECT_GT(ratio, 1.45);
        EXPECT_LT(ratio, 4.6);
        EXPECT_EQ(close[i]["camera"]["eye"], full[i]["camera"]["eye"]);
        EXPECT_NE(close[i]["camera"]["target"], full[i]["camera"]["target"]);
    }
}

// Samplers: items of the textured planes draw theirs from the dataset's list, and every record names
// the sampler its scene read textures with ("none" without textures); the default list is what older
// datasets hold and writes no "samplers" key; the other choices of an item do not depend on it.
TEST(DatasetGenerate, TexturedItemsDrawTheirSamplerFromTheList) {
    DatasetSpec spec = allFamilies(5);
    EXPECT_FALSE(spec.toJson().contains("samplers"));
    spec.samplers = {"fourier", "trilinear"};
    EXPECT_EQ(DatasetSpec::fromJson(spec.toJson()).samplers, spec.samplers);
    for (const std::vector<std::string>& bad :
         {std::vector<std::string>{}, {"trilinear", "trilinear"}, {"gaussian"}}) {
        spec.samplers = bad;
        EXPECT_THROW(spec.validate(), Error);
    }
    testing::TempDir dir;
    const std::string recipe =
        "data generate --families textures,shapes --test-families none --count 6 "
        "--size 48x48 --truth 8 --quiet --out '";
    ASSERT_EQ(run(recipe + dir.file("default") + "'"), 0);
    ASSERT_EQ(run(recipe + dir.file("fourier") + "' --samplers fourier"), 0);
    std::string err;
    EXPECT_EQ(run(recipe + dir.file("bad") + "' --samplers point,gaussian", &err), 2);
    EXPECT_NE(err.find("gaussian"), std::string::npos) << err;
    EXPECT_EQ(err.find('\n'), err.size() - 1) << err;  // one line
    EXPECT_FALSE(std::filesystem::exists(dir.file("bad")));
    const std::vector<nlohmann::json> before = readManifest(dir.file("default")),
                                      after = readManifest(dir.file("fourier"));
    ASSERT_EQ(before.size(), 6u);
    ASSERT_EQ(after.size(), 6u);
    std::set<std::string> drawn;
    for (size_t i = 0; i < 6; ++i) {
        const bool textured = after[i]["family"] == "textures";
        if (textured) drawn.insert(before[i]["sampler"].get<std::string>());
        EXPECT_EQ(after[i]["sampler"], textured ? "fourier" : "none");
        EXPECT_EQ(before[i]["sampler"] == "none", !textured);
        EXPECT_EQ(after[i]["camera"], before[i]["camera"]);
        EXPECT_EQ(after[i]["light"], before[i]["light"]);
        if (after[i]["family"] == "shapes") {  // no texture: the same frames
            EXPECT_EQ(slurp(dir.file("fourier") + "/items/shapes/" + after[i]["id"].get<std::string>() +
                            "_truth.exr"),
                      slurp(dir.file("default") + "/items/shapes/" + before[i]["id"].get<std::string>() +
                            "_truth.exr"));
        }
    }
    EXPECT_FALSE(drawn.count("fourier"));
    // data stats counts the samplers of textured items only.
    const nlohmann::json stats = datasetStats(dir.file("fourier"));
    EXPECT_EQ(stats["samplers"], nlohmann::json({{"fourier", 3}}));
    EXPECT_EQ(stats["families"]["textures"]["samplers"]["fourier"].get<int>(), 3);
    EXPECT_FALSE(stats["families"]["shapes"].contains("samplers"));
    // A dataset is resumed only with the list it was made with.
    EXPECT_NE(run(recipe + dir.file("fourier") + "' --samplers trilinear", &err), 0);
}

TEST(DatasetGenerate, KillNineThenTheSameCommandEqualsAnUninterruptedRun) {
    testing::TempDir dir;
    const std::string whole = dir.file("whole"), broken = dir.file("broken");
    const std::string slow =
        "data generate --families shapes,pipes,thin --test-families none --count 9 "
        "--size 128x128 --truth 64 --quiet";
    ASSERT_EQ(run(slow + " --workers 2 --out '" + whole + "'"), 0);
    // Start the same generation in its own process group and kill the whole group mid-way.
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
        ::setpgid(0, 0);
        const std::string command = "exec '" + std::string(DEJAG_BINARY) + "' " + slow +
                                    " --workers 1 --out '" + broken + "' 2>/dev/null";
        ::execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
        _exit(127);
    }
    ::setpgid(pid, pid);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    bool killedMidway = false;
    while (std::chrono::steady_clock::now() < deadline) {
        if (readManifest(broken).size() >= 3) {
            killedMidway = ::kill(-pid, SIGKILL) == 0;
            break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    int status = 0;
    ::waitpid(pid, &status, 0);
    ASSERT_TRUE(killedMidway);
    EXPECT_TRUE(WIFSIGNALED(status));
    EXPECT_LT(readManifest(broken).size(), 9u);
    ASSERT_EQ(run(slow + " --workers 2 --out '" + broken + "'"), 0);
    expectSameFiles(broken, whole);
}

TEST(DatasetVerify, CatchesCorruptMissingAndExtraFiles) {
    testing::TempDir dir;
    const std::string out = dir.file("tiny");
    ASSERT_EQ(run(kTiny + " --out '" + out + "'"), 0);
    const std::vector<nlohmann::json> records = readManifest(out);
    const fs::path truth = fs::path(out) / records[3]["files"]["truth"]["path"].get<std::string>();
    std::string bytes = slurp(truth);
    bytes[bytes.size() / 2] ^= 0x20;
    std::ofstream(truth, std::ios::binary) << bytes;
    std::string err;
    EXPECT_EQ(run("data verify '" + out + "'", &err), 2);
    EXPECT_NE(err.find("000003"), std::string::npos) << err;
    EXPECT_NE(err.find("checksum"), std::string::npos) << err;
    fs::remove(fs::path(out) / records[5]["files"]["input"]["path"].get<std::string>());
    std::ofstream(fs::path(out) / "items" / "stray.exr") << "x";
    const VerifyReport report = verifyDataset(out);
    EXPECT_EQ(report.problems.size(), 3u);
    std::string all;
    for (const std::string& p : report.problems) all += p + "\n";
    EXPECT_NE(all.find("missing"), std::string::npos) << all;
    EXPECT_NE(all.find("extra file items/stray.exr"), std::string::npos) << all;
}

// Found by fuzz/fuzz_manifest.cpp: a record without the numbers `data stats` reads threw a JSON type error
// from deep inside the library. Every record is now checked as it is read; a bad one is refused with its
// line and what is wrong, and nothing reads outside the dataset folder.
TEST(DatasetManifest, BadRecordsAreRefusedNamingTheLineAndTheField) {
    testing::TempDir dir;
    const nlohmann::json valid = {{"index", 0},
                                  {"id", "shapes-000000"},
                                  {"family", "shapes"},
                                  {"split", "train"},
                                  {"size", {64, 48}},
                                  {"edge_fraction", 0.1},
                                  {"aliased_psnr", 30.0},
                                  {"files",
                                   {{"input", {{"path", "items/a.exr"}, {"bytes", 10}, {"checksum", "0"}}},
                                    {"truth", {{"path", "items/b.exr"}, {"bytes", 10}, {"checksum", "0"}}}}}};
    auto withManifest = [&](const std::string& lines) {
        fs::create_directories(dir.file("d"));
        std::ofstream(dir.file("d/manifest.jsonl"), std::ios::trunc) << lines;
        return dir.file("d");
    };
    EXPECT_EQ(readManifest(withManifest(valid.dump() + "\n")).size(), 1u);
    {
        // A flat item (its 1-sample frame equal to its truth) is listed by `data stats`.
        nlohmann::json flat = valid;
        flat["index"] = 1, flat["id"] = "shapes-000001", flat["aliased_psnr"] = 158.3;
        const std::string folder = withManifest(valid.dump() + "\n" + flat.dump() + "\n");
        const nlohmann::json stats = datasetStats(folder);
        ASSERT_EQ(stats["flat_items"].size(), 1u);
        EXPECT_EQ(stats["flat_items"][0]["id"], "shapes-000001");
        std::string out;
        EXPECT_EQ(run("data stats '" + folder + "'", nullptr, &out), 0);
        EXPECT_NE(out.find("1 item with nothing to anti-alias"), std::string::npos) << out;
        EXPECT_NE(out.find("shapes-000001 (shapes, train)"), std::string::npos) << out;
    }
    struct Case {
        std::function<void(nlohmann::json&)> change;
        std::string expected;
    };
    const Case cases[] = {
        {[](nlohmann::json& r) { r.erase("aliased_psnr"); }, "aliased_psnr"},
        {[](nlohmann::json& r) { r["index"] = "three"; }, "index"},
        {[](nlohmann::json& r) { r["size"] = {64}; }, "size"},
        {[](nlohmann::json& r) { r["files"].erase("truth"); }, "files.truth"},
        {[](nlohmann::json& r) { r["files"]["input"]["bytes"] = -1; }, "files.input"},
        {[](nlohmann::json& r) { r["files"]["input"]["path"] = "../../etc/passwd"; }, "inside the dataset"},
        {[](nlohmann::json& r) { r = 5; }, "not a JSON object"},
        {[](nlohmann::json& r) {
             r["sequence"] = {{"length", 4}, {"move", {{"kind", "pan"}, {"cut", -1}}}};
         },
         "'motion'"},
        {[](nlohmann::json& r) {
             r["sequence"] = {{"length", 4}};
         },
         "'sequence'"},
    };
    for (const Case& c : cases) {
        nlohmann::json bad = valid;
        c.change(bad);
        const std::string folder = withManifest(valid.dump() + "\n" + bad.dump() + "\n");
        try {
            (void)datasetStats(folder);
            ADD_FAILURE() << "accepted " << bad.dump();
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find("line 2"), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find(c.expected), std::string::npos) << e.what();
        }
        std::string err;
        EXPECT_EQ(run("data stats '" + folder + "'", &err), 2);
        EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    }
}

TEST(DatasetGenerate, BadInputIsOneLineAndOverwritesNothing) {
    testing::TempDir dir;
    const std::string out = dir.file("tiny");
    std::string err;
    EXPECT_EQ(run("data generate --families shapes,teapots --count 4 --out '" + out + "'", &err), 2);
    EXPECT_NE(err.find("teapots"), std::string::npos) << err;
    EXPECT_EQ(run("data generate --families shapes --count 0 --out '" + out + "'", &err), 2);
    EXPECT_NE(err.find("--count"), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(out));
    ASSERT_EQ(run(kTiny + " --out '" + out + "'"), 0);
    const auto before = contents(out);
    EXPECT_EQ(
        run("data generate --families shapes,pipes,thin,foliage,random --test-families foliage --count 10 "
            "--size 64x64 --truth 8 --quiet --out '" +
                out + "'",
            &err),
        2);
    EXPECT_NE(err.find("different dataset"), std::string::npos) << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    EXPECT_TRUE(contents(out) == before);
}

// ---- Sequences ------------------------------------------------------------------------------------------

TEST(DatasetSequences, PlansDrawMovesWithoutChangingTheItemsOfSingleFrames) {
    DatasetSpec single = allFamilies(400), sequences = allFamilies(400);
    sequences.sequenceLength = 8;
    std::map<std::string, int> kinds;
    int cuts = 0, frozen = 0;
    double slowest = 1e9, fastest = 0;
    for (int i = 0; i < sequences.count; ++i) {
        const ItemPlan a = planItem(single, i), b = planItem(sequences, i);
        EXPECT_EQ(a.scene, b.scene);
        EXPECT_EQ(a.seed, b.seed);
        EXPECT_EQ(a.split, b.split);
        EXPECT_EQ(a.time, b.time);
        EXPECT_EQ(a.move.kind, "still");  // single frames do not move
        ++kinds[b.move.kind];
        if (b.move.kind != "still")
            slowest = std::min(slowest, b.move.speed), fastest = std::max(fastest, b.move.speed);
        else
            EXPECT_EQ(b.move.speed, 0.0);
        if (b.move.cut >= 0) {
            ++cuts;
            EXPECT_GE(b.move.cut, 2);
            EXPECT_LE(b.move.cut, 6);
        }
        frozen += b.move.timeStep == 0;
        EXPECT_GE(b.move.jitterStart, 0);
        EXPECT_LT(b.move.jitterStart, 16);
    }
    for (const char* kind : {"still", "pan", "orbit", "dolly"}) EXPECT_GT(kinds[kind], 30) << kind;
    EXPECT_GT(cuts, 30);
    EXPECT_LT(cuts, 100);
    EXPECT_GT(frozen, 100);
    EXPECT_LT(slowest, 0.2);
    EXPECT_GT(fastest, 6.0);
    EXPECT_EQ(DatasetSpec::fromJson(sequences.toJson()).toJson(), sequences.toJson());
    EXPECT_FALSE(single.toJson().contains("sequence"));  // the single-frame dataset.json is unchanged
    sequences.sequenceLength = 0;
    EXPECT_THROW(sequences.validate(), Error);
    sequences.sequenceLength = 8, sequences.jitterSpread = -1;
    EXPECT_THROW(sequences.validate(), Error);
}

// Bilinear read of an image's channels c .. c + 2 at pixel coordinates (centres at + 0.5), clamped.
std::array<double, 3> bilinear(const Image& image, int c, double x, double y) {
    x -= 0.5, y -= 0.5;
    const int x0 = int(std::floor(x)), y0 = int(std::floor(y));
    const double fx = x - x0, fy = y - y0;
    std::array<double, 3> v{};
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
            const int px = std::clamp(x0 + dx, 0, image.width - 1),
                      py = std::clamp(y0 + dy, 0, image.height - 1);
            const double w = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy);
            for (int k = 0; k < 3; ++k) v[size_t(k)] += w * image.at(px, py, c + k);
        }
    return v;
}

// A sequence's motion vectors say where each pixel was: each frame's truth matches the previous frame's
// truth read at p - motion better than read where it is, and far better than read at p + motion.
TEST(DatasetSequences, MotionVectorsCarryEachTruthOntoTheNext) {
    DatasetSpec spec;
    spec.families = {"shapes", "pipes", "foliage"}, spec.testFamilies = {"foliage"};
    spec.count = 300, spec.width = 96, spec.height = 64, spec.truthSamples = 16, spec.adaptive = false;
    spec.sequenceLength = 4;
    testing::TempDir dir;
    ItemRenderer renderer;
    int checked = 0;
    for (const char* kind : {"pan", "orbit", "dolly"}) {
        int index = 0;
        for (; index < spec.count; ++index) {
            const ItemPlan p = planItem(spec, index);
            if (p.move.kind == kind && p.move.speed > 1.5 && p.move.cut < 0 && p.family == "pipes") break;
        }
        ASSERT_LT(index, spec.count) << kind;
        const ItemPlan plan = planItem(spec, index);
        const nlohmann::json record = renderer.render(spec, plan, dir.path().string());
        EXPECT_EQ(record["files"].size(), size_t(2 * spec.sequenceLength + 1));
        EXPECT_GT(record["motion"]["moving_fraction"].get<double>(), 0.1) << kind;
        for (int k = 1; k < spec.sequenceLength; ++k) {
            const Image frame = readImage((fs::path(dir.path()) / plan.sequenceFile("frame", k)).string());
            const Image truth = readImage((fs::path(dir.path()) / plan.sequenceFile("truth", k)).string());
            const Image previous =
                readImage((fs::path(dir.path()) / plan.sequenceFile("truth", k - 1)).string());
            const int mx = frame.findChannel("motion.X"), my = frame.findChannel("motion.Y");
            ASSERT_GE(mx, 0);
            ASSERT_GE(frame.findChannel("prevdepth.Z"), 0);
            double warped = 0, flipped = 0, still = 0;
            int n = 0;
            for (int y = 4; y < frame.height - 4; ++y)
                for (int x = 4; x < frame.width - 4; ++x) {
                    const double vx = frame.at(x, y, mx), vy = frame.at(x, y, my);
                    if (vx == 0 && vy == 0) continue;  // the background: no geometry, no motion
                    const std::array<double, 3> was = bilinear(previous, 0, x + 0.5 - vx, y + 0.5 - vy),
                                                wrongWay = bilinear(previous, 0, x + 0.5 + vx, y + 0.5 + vy);
                    for (int c = 0; c < 3; ++c) {
                        warped += std::abs(truth.at(x, y, c) - was[size_t(c)]);
                        flipped += std::abs(truth.at(x, y, c) - wrongWay[size_t(c)]);
                        still += std::abs(truth.at(x, y, c) - previous.at(x, y, c));
                    }
                    ++n;
                }
            ASSERT_GT(n, 100) << kind;
            // (Not all of the difference goes: the bilinear read blurs, and the highlights move with the
            // view — an orbit turns the view while moving near pixels less than a pan, so there that is
            // most of what changes. The wrong sign of the motion is far worse everywhere.)
            if (std::string(kind) != "orbit") {
                EXPECT_LT(warped, 0.75 * still) << kind << " frame " << k;
            }
            EXPECT_LT(warped, 0.5 * flipped) << kind << " frame " << k;
            ++checked;
        }
    }
    EXPECT_EQ(checked, 9);
}

const std::string kTinySequences =
    "data generate --families shapes,hair,foliage --test-families foliage --count 4 --size 48x40 --truth 8 "
    "--sequence-length 5 --quiet";

TEST(DatasetSequences, GenerateVerifyStatsAndRedoAPartialSequence) {
    testing::TempDir dir;
    const std::string whole = dir.file("whole"), broken = dir.file("broken");
    ASSERT_EQ(run(kTinySequences + " --workers 2 --out '" + whole + "'"), 0);
    EXPECT_TRUE(verifyDataset(whole).ok());
    const std::vector<nlohmann::json> records = readManifest(whole);
    ASSERT_EQ(records.size(), 4u);
    for (const nlohmann::json& r : records) {
        EXPECT_EQ(r["files"].size(), 11u);
        const fs::path folder =
            fs::path(whole) / "items" / r["family"].get<std::string>() / r["id"].get<std::string>();
        std::ifstream in(folder / "render.json");
        const nlohmann::json sidecar = nlohmann::json::parse(in);
        ASSERT_EQ(sidecar["frames"].size(), 5u);
        for (const nlohmann::json& f : sidecar["frames"]) {
            EXPECT_TRUE(fs::exists(folder / f["file"].get<std::string>()));
            for (int a = 0; a < 2; ++a) EXPECT_LE(std::abs(f["jitter_pixels"][a].get<double>()), 0.5);
        }
        EXPECT_EQ(sidecar["cuts"].size(), r["sequence"]["move"]["cut"].get<int>() >= 0 ? 1u : 0u);
    }
    const nlohmann::json stats = datasetStats(whole);
    ASSERT_TRUE(stats.contains("motion"));
    EXPECT_EQ(stats["motion"]["sequences"].get<int>(), 4);
    std::string out;
    EXPECT_EQ(run("data stats '" + whole + "'", nullptr, &out), 0);
    EXPECT_NE(out.find("camera moves:"), std::string::npos) << out;
    // Single-frame readers refuse a dataset of sequences in one line.
    std::string err;
    EXPECT_EQ(run("data stats '" + whole + "' --sampler", &err), 2);
    EXPECT_NE(err.find("sequences"), std::string::npos) << err;

    // An item half-written when the run stopped (its record not in the manifest, a truth missing, a
    // temporary file left) is rendered again, to the same bytes.
    fs::copy(whole, broken, fs::copy_options::recursive);
    std::string manifest = slurp(fs::path(broken) / "manifest.jsonl");
    manifest.erase(manifest.rfind('\n', manifest.size() - 2) + 1);
    std::ofstream(fs::path(broken) / "manifest.jsonl", std::ios::trunc) << manifest;
    const nlohmann::json last = records.back();
    fs::remove(fs::path(broken) / last["files"]["truth_0003"]["path"].get<std::string>());
    std::ofstream((fs::path(broken) / last["files"]["frame_0001"]["path"].get<std::string>()).string() +
                  ".tmp-9")
        << "x";
    EXPECT_FALSE(verifyDataset(broken).ok());
    ASSERT_EQ(run(kTinySequences + " --workers 1 --out '" + broken + "'"), 0);
    expectSameFiles(broken, whole);
    // dejag filter reads a sequence's folder with its jitter and restarts the history at its cuts.
    {
        const fs::path sequence = fs::path(whole) / records[0]["files"]["render"]["path"].get<std::string>();
        std::ifstream in(sequence);
        nlohmann::json sidecar = nlohmann::json::parse(in);
        in.close();
        sidecar["cuts"] = {3};
        std::ofstream(sequence, std::ios::trunc) << sidecar.dump();
        ASSERT_EQ(run("filter --method taa-hq --json '" + sequence.parent_path().string() + "' '" +
                          dir.file("filtered/") + "'",
                      &err, &out),
                  0)
            << err;
        const nlohmann::json result = nlohmann::json::parse(out);
        ASSERT_EQ(result["frames"].size(), 5u);
        for (int k = 0; k < 5; ++k) EXPECT_EQ(result["frames"][k]["history_reset"].get<bool>(), k == 3) << k;
    }
    // The jitter spread is a sequence's setting.
    EXPECT_EQ(
        run("data generate --families shapes --count 1 --size 48x40 --truth 8 --jitter-spread 0.5 --out '" +
                dir.file("x") + "'",
            &err),
        2);
    EXPECT_NE(err.find("--jitter-spread"), std::string::npos) << err;
}

}  // namespace
}  // namespace dejag::data
