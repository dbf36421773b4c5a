// Crash safety: `dejag data generate` and `dejag train` killed with SIGKILL at 20 random moments each,
// restarted every time with the same command, end exactly where an uninterrupted run ends (the same
// dataset files, bit for bit; the same final weights, bit for bit). Every restart must succeed: a
// partial file taken as complete would make it fail or differ.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "nn/model.h"
#include "tests/test_util.h"

namespace dejag {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// Starts the dejag binary with `arguments` in its own process group; returns its pid.
pid_t start(const std::string& arguments) {
    const pid_t pid = ::fork();
    if (pid == 0) {
        ::setpgid(0, 0);
        const std::string command =
            "exec '" + std::string(DEJAG_BINARY) + "' " + arguments + " >/dev/null 2>&1";
        ::execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
        _exit(127);
    }
    ::setpgid(pid, pid);
    return pid;
}

// Waits for pid; its exit status, or -signal if a signal ended it.
int wait(pid_t pid) {
    int status = 0;
    ::waitpid(pid, &status, 0);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
}

// Runs `arguments` to the end; returns the exit status and the seconds it took.
std::pair<int, double> runToEnd(const std::string& arguments) {
    const auto begin = Clock::now();
    const int status = wait(start(arguments));
    return {status, std::chrono::duration<double>(Clock::now() - begin).count()};
}

// Runs `arguments` 20 times, killing it (its whole process group: worker processes too) each time, then
// once more to the end. progress() measures how far the job got (dataset records, checkpoint step;
// `finalProgress` at the end): kill k waits until the job reaches the k-th of 20 sorted random points
// of progress, then a random 0-40 ms more (landing inside item renders, checkpoint writes and manifest
// appends), then kills. Returns how many runs were killed before they finished.
int killTwentyTimesThenFinish(const std::string& arguments, int finalProgress, uint64_t seed,
                              const std::function<int()>& progress) {
    std::mt19937_64 random(seed);
    std::vector<int> targets(20);
    for (int& t : targets) t = std::uniform_int_distribution<int>(0, std::max(0, finalProgress - 1))(random);
    std::sort(targets.begin(), targets.end());
    std::uniform_int_distribution<int> delayMs(0, 40);
    std::set<int> progressAtKills;
    int killed = 0;
    for (int k = 0; k < 20; ++k) {
        const pid_t pid = start(arguments);
        int status = 0;
        bool exited = false;
        auto poll = [&] {
            if (::waitpid(pid, &status, WNOHANG) == pid) exited = true;
            return exited;
        };
        while (!poll() && progress() < targets[size_t(k)])
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
        const auto until = Clock::now() + std::chrono::milliseconds(delayMs(random));
        while (!exited && Clock::now() < until && !poll())
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
        if (!exited) {
            ::kill(-pid, SIGKILL);
            killed += wait(pid) == -SIGKILL;
            progressAtKills.insert(progress());
        } else {
            EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "restart " << k << " failed";
        }
    }
    EXPECT_EQ(runToEnd(arguments).first, 0) << "the last restart failed";
    std::string points;
    for (const int p : progressAtKills) points += " " + std::to_string(p);
    std::printf(
        "[   INFO   ] %d of 20 runs killed (SIGKILL) before they finished; progress after the kills:%s "
        "(of %d)\n",
        killed, points.c_str(), finalProgress);
    EXPECT_GE(progressAtKills.size(), 3u) << "the kills should land at several points of the job";
    return killed;
}

using testing::expectSameFiles;
using testing::slurp;

// log.csv without its second column (seconds since the start).
std::string withoutSeconds(const std::string& csv) {
    std::stringstream in(csv), out;
    std::string line;
    while (std::getline(in, line)) {
        const size_t first = line.find(','), second = line.find(',', first + 1);
        out << (first == std::string::npos || second == std::string::npos
                    ? line
                    : line.substr(0, first) + line.substr(second))
            << '\n';
    }
    return out.str();
}

const std::string kDataset =
    "data generate --families shapes,pipes,foliage --test-families foliage --count 9 --size 64x64 --truth 8 "
    "--quiet";

TEST(CrashSafety, DatasetGenerationKilledTwentyTimesEndsWithTheSameFiles) {
    testing::TempDir dir;
    ASSERT_EQ(runToEnd(kDataset + " --out '" + dir.file("whole") + "'").first, 0);
    auto records = [&](const std::string& folder) {
        std::ifstream manifest(fs::path(dir.file(folder)) / "manifest.jsonl");
        std::string line;
        int count = 0;
        while (std::getline(manifest, line)) count += !line.empty();
        return count;
    };
    const std::string interrupted = kDataset + " --out '" + dir.file("killed") + "'";
    const int killed =
        killTwentyTimesThenFinish(interrupted, records("whole"), 20261122, [&] { return records("killed"); });
    EXPECT_GE(killed, 15) << "most kills should land while the command runs";
    expectSameFiles(dir.file("whole"), dir.file("killed"));
}

TEST(CrashSafety, TrainingKilledTwentyTimesEndsWithTheSameWeights) {
    testing::TempDir dir;
    ASSERT_EQ(runToEnd(kDataset + " --out '" + dir.file("data") + "'").first, 0);
    auto train = [&](const std::string& out) {
        return "train --data '" + dir.file("data") + "' --out '" + dir.file(out) +
               "' --arch fast --steps 40 --batch 2 --patch 32 --eval-every 10 --checkpoint-every 3 "
               "--val-images 2 --threads 2 --quiet --resume";
    };
    ASSERT_EQ(runToEnd(train("whole")).first, 0);
    // Progress: the step of the last checkpoint (written every 3 steps), from its metadata.
    auto checkpointStep = [&](const std::string& folder) {
        try {
            const std::string bytes = slurp(fs::path(dir.file(folder)) / "checkpoint.safetensors");
            uint64_t headerSize = 0;
            if (bytes.size() < 8) return 0;
            std::memcpy(&headerSize, bytes.data(), 8);
            const nlohmann::json header = nlohmann::json::parse(bytes.substr(8, headerSize));
            return nlohmann::json::parse(header["__metadata__"]["dejag.state"].get<std::string>())["step"]
                .get<int>();
        } catch (const std::exception&) {
            return 0;
        }
    };
    const int killed = killTwentyTimesThenFinish(train("killed"), checkpointStep("whole"), 7,
                                                 [&] { return checkpointStep("killed"); });
    EXPECT_GE(killed, 15) << "most kills should land while the command runs";
    const nn::Model a = nn::loadModel((fs::path(dir.file("whole")) / "final.safetensors").string());
    const nn::Model b = nn::loadModel((fs::path(dir.file("killed")) / "final.safetensors").string());
    ASSERT_EQ(a.parameterCount(), b.parameterCount());
    EXPECT_EQ(std::memcmp(a.parameterData(), b.parameterData(), size_t(a.parameterCount()) * sizeof(float)),
              0)
        << "final weights differ after " << killed << " kills";
    // The same log, but for the wall-clock column.
    EXPECT_EQ(withoutSeconds(slurp(fs::path(dir.file("whole")) / "log.csv")),
              withoutSeconds(slurp(fs::path(dir.file("killed")) / "log.csv")));
}

}  // namespace
}  // namespace dejag
