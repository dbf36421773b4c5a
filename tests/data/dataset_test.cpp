// Datasets: item plans and splits, generation through the binary (worker processes), resume after
// kill -9, verify and stats, bad input.
#include "data/dataset.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <thread>

#include "base/error.h"
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

}  // namespace
}  // namespace dejag::data
