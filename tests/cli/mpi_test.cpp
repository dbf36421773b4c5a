// dejag-mpi on localhost (docs/mpi.md): `mpirun --oversubscribe -np 2`, as CI runs it. Training on two
// ranks gives the weights of one process running the same micro-batches, bit for bit, and a run whose
// rank died resumes on any number of processes to the same weights; dataset generation on two ranks writes
// the same dataset as one process, and resumes after a rank died.
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "nn/safetensors.h"
#include "tests/cli/cli_util.h"

namespace dejag {
namespace {

namespace fs = std::filesystem;

// mpirun as CI runs it: as root, two ranks on a machine of two cores, no single-copy transport (which
// containers often forbid). Leak checking is off for the ranks (sanitizer builds): Open MPI unloads its
// plug-ins at MPI_Finalize, so what they keep shows as "<unknown module>" leaks that no suppression by
// library name can match. AddressSanitizer still checks every memory access.
RunResult mpirun(int ranks, const std::string& arguments, const testing::TempDir& dir) {
    const std::string out = dir.file("mpi_stdout.txt"), err = dir.file("mpi_stderr.txt");
    const std::string command =
        "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "
        "OMPI_MCA_btl_vader_single_copy_mechanism=none ASAN_OPTIONS=detect_leaks=0 "
        "mpirun -x ASAN_OPTIONS --oversubscribe -np " +
        std::to_string(ranks) + " '" + std::string(DEJAG_MPI_BINARY) + "' " + arguments + " >'" + out +
        "' 2>'" + err + "'";
    const int status = std::system(command.c_str());
    RunResult result;
    result.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    result.out = slurp(out);
    result.err = slurp(err);
    fs::remove(out);
    fs::remove(err);
    return result;
}

// The weights of a model file, bit for bit (its metadata name the command, which differs).
void expectSameWeights(const std::string& a, const std::string& b) {
    const nn::SafetensorsFile x = nn::readSafetensors(a), y = nn::readSafetensors(b);
    ASSERT_EQ(x.tensors.size(), y.tensors.size());
    for (const auto& [name, t] : x.tensors) {
        SCOPED_TRACE(name);
        ASSERT_EQ(t.shape, y.at(name).shape);
        EXPECT_EQ(t.f32, y.at(name).f32);
    }
}

size_t linesStartingWith(const std::string& text, const std::string& prefix) {
    size_t count = 0;
    for (size_t at = 0; at < text.size();) {
        const size_t end = text.find('\n', at);
        if (text.compare(at, prefix.size(), prefix) == 0) ++count;
        if (end == std::string::npos) break;
        at = end + 1;
    }
    return count;
}
size_t linesContaining(const std::string& text, const std::string& part) {
    size_t count = 0;
    for (size_t at = 0; (at = text.find(part, at)) != std::string::npos; at += part.size()) ++count;
    return count;
}

TEST(Mpi, TrainingOnTwoRanksEqualsOneProcessAndResumesAfterARankDies) {
    testing::TempDir dir;
    RunResult r =
        run("data generate --out '" + dir.file("data") + "' --count 24 --size 64x64 --truth 8 --quiet", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const std::string common =
        " --data '" + dir.file("data") +
        "' --steps 6 --batch 4 --patch 32 --threads 1 --eval-every 3 --checkpoint-every 2";
    r = run("train" + common + " --out '" + dir.file("one") + "' --micro-batches 2 --quiet", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;

    // Two ranks, one micro-batch each (the default): rank 0 alone speaks and writes.
    r = mpirun(2, "train" + common + " --out '" + dir.file("two") + "' --json", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(linesContaining(r.out, "\"event\":\"finished\""), 1u) << r.out;
    const nlohmann::json record = nlohmann::json::parse(slurp(dir.file("two/run.json")));
    EXPECT_EQ(record["finished"]["ranks"], 2);
    EXPECT_EQ(record["finished"]["micro_batches"], 2);
    EXPECT_GT(record["finished"]["communication_seconds"].get<double>(), 0.0);
    expectSameWeights(dir.file("one/final.safetensors"), dir.file("two/final.safetensors"));
    expectSameWeights(dir.file("one/best.safetensors"), dir.file("two/best.safetensors"));

    // Four micro-batches on two ranks, two each: still summed one after the other as one process does
    // (a sum of each rank's own first would round differently).
    r = run("train" + common + " --out '" + dir.file("one4") + "' --micro-batches 4 --quiet", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    r = mpirun(2, "train" + common + " --out '" + dir.file("two4") + "' --micro-batches 4 --quiet", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    expectSameWeights(dir.file("one4/final.safetensors"), dir.file("two4/final.safetensors"));

    // Rank 1 dies at step 3: the job ends with mpirun's word for it, the step-2 checkpoint intact; one
    // process resumes it (the run keeps its two micro-batches) to the same weights.
    r = mpirun(2, "train" + common + " --out '" + dir.file("killed") + "' --quiet --kill-rank-at 1:3", dir);
    EXPECT_NE(r.exitCode, 0);
    EXPECT_NE(r.err.find("rank 1"), std::string::npos) << r.err;
    ASSERT_TRUE(fs::exists(dir.file("killed/checkpoint.safetensors")));
    EXPECT_FALSE(fs::exists(dir.file("killed/final.safetensors")));
    r = run("train" + common + " --out '" + dir.file("killed") + "' --resume --quiet", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    expectSameWeights(dir.file("one/final.safetensors"), dir.file("killed/final.safetensors"));

    // A batch the ranks cannot share equally, and an error every rank meets: one line, from rank 0.
    r = mpirun(2, "train" + common + " --out '" + dir.file("odd") + "' --micro-batches 3 --quiet", dir);
    EXPECT_NE(r.exitCode, 0);
    EXPECT_EQ(linesStartingWith(r.err, "dejag train"), 1u) << r.err;
    EXPECT_NE(r.err.find("does not split into 3"), std::string::npos) << r.err;
}

// A recurrent network, unrolled over each crop's frames: its micro-batches are crops of sequences.
TEST(Mpi, TemporalTrainingOnTwoRanksEqualsOneProcess) {
    testing::TempDir dir;
    RunResult r = run("data generate --out '" + dir.file("data") +
                          "' --count 30 --size 32x32 --truth 4 --sequence-length 3 --quiet",
                      dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const std::string common =
        " --data '" + dir.file("data") +
        "' --steps 4 --batch 4 --patch 32 --frames 3 --arch accumulate:8x2 --threads 1 "
        "--eval-every 2 --micro-batches 4 --quiet";
    r = run("train" + common + " --out '" + dir.file("one") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    r = mpirun(2, "train" + common + " --out '" + dir.file("two") + "'", dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    expectSameWeights(dir.file("one/final.safetensors"), dir.file("two/final.safetensors"));
}

// Any other command would run whole on every rank, each writing the same files: refused, in one line.
TEST(Mpi, CommandsThatDoNotShareTheirWorkAreRefused) {
    testing::TempDir dir;
    for (const char* command : {"render --scene sphere --out x", "filter a.png b.png",
                                "train export run m.safetensors", "data verify d"}) {
        SCOPED_TRACE(command);
        const RunResult r = mpirun(2, command, dir);
        EXPECT_NE(r.exitCode, 0);
        EXPECT_EQ(linesStartingWith(r.err, "dejag-mpi: '"), 1u) << r.err;
        EXPECT_NE(r.err.find("share their work"), std::string::npos) << r.err;
    }
    EXPECT_EQ(filesIn(dir.path()), 0u);
}

TEST(Mpi, GenerationOnTwoRanksEqualsOneProcessAndResumesAfterARankDies) {
    testing::TempDir dir;
    const std::string spec = " --count 8 --size 48x48 --truth 8 --workers 1 --quiet";
    RunResult r = run("data generate --out '" + dir.file("one") + "'" + spec, dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    r = mpirun(2, "data generate --out '" + dir.file("two") + "'" + spec, dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    // The manifest holds every file's checksum: equal manifests, equal datasets.
    EXPECT_EQ(slurp(dir.file("one/manifest.jsonl")), slurp(dir.file("two/manifest.jsonl")));
    for (const auto& entry : fs::directory_iterator(dir.file("two")))  // no rank's manifest is left
        EXPECT_EQ(entry.path().filename().string().find("manifest.rank-"), std::string::npos) << entry.path();

    // Rank 1 dies after its second item; running the job again renders what is missing.
    r = mpirun(2, "data generate --out '" + dir.file("killed") + "'" + spec + " --kill-rank-at 1:2", dir);
    EXPECT_NE(r.exitCode, 0);
    EXPECT_NE(r.err.find("rank 1"), std::string::npos) << r.err;
    r = mpirun(2, "data generate --out '" + dir.file("killed") + "' --json" + spec, dir);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_LT(nlohmann::json::parse(r.out)["rendered"].get<int>(), 8) << r.out;
    EXPECT_EQ(slurp(dir.file("one/manifest.jsonl")), slurp(dir.file("killed/manifest.jsonl")));
    r = run("data verify '" + dir.file("killed") + "'", dir);
    EXPECT_EQ(r.exitCode, 0) << r.out << r.err;
}

}  // namespace
}  // namespace dejag
