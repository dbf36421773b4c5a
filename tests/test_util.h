// Helpers shared by the test suites.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include <ostream>
#include <vector>

#include "base/simd.h"

namespace dejag::testing {

// The bytes of a file ("" if it cannot be read).
inline std::string slurp(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

// Every file below a folder: relative path -> bytes.
inline std::map<std::string, std::string> contents(const std::filesystem::path& folder) {
    std::map<std::string, std::string> files;
    for (const auto& entry : std::filesystem::recursive_directory_iterator(folder))
        if (entry.is_regular_file())
            files[std::filesystem::relative(entry.path(), folder).string()] = slurp(entry.path());
    return files;
}

// Two folders hold the same file names and bytes (reported by name, not by dumping the bytes).
inline void expectSameFiles(const std::filesystem::path& a, const std::filesystem::path& b) {
    const auto left = contents(a), right = contents(b);
    std::set<std::string> names;
    for (const auto& [name, bytes] : left) names.insert(name);
    for (const auto& [name, bytes] : right) names.insert(name);
    for (const std::string& name : names) {
        const bool inLeft = left.count(name) > 0, inRight = right.count(name) > 0;
        EXPECT_TRUE(inLeft && inRight) << name << " is only in " << (inLeft ? a : b);
        if (inLeft && inRight) {
            EXPECT_TRUE(left.at(name) == right.at(name)) << name << " differs";
        }
    }
}

inline std::string sourcePath(const std::string& relative) {
    return std::string(DEJAG_SOURCE_DIR) + "/" + relative;
}

// A fresh folder per test, removed afterwards.
class TempDir {
  public:
    TempDir() {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        path_ = std::filesystem::temp_directory_path() /
                ("dejag-test-" + std::to_string(::getpid()) + "-" + std::string(info->test_suite_name()) +
                 "-" + info->name());
        std::filesystem::remove_all(path_);
        std::filesystem::create_directories(path_);
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path_, ec);
    }
    std::string file(const std::string& name) const { return (path_ / name).string(); }
    const std::filesystem::path& path() const { return path_; }

  private:
    std::filesystem::path path_;
};

// Every SIMD level this CPU can run (all three on the development machine), for tests that cover each.
inline std::vector<SimdLevel> availableSimdLevels() {
    std::vector<SimdLevel> levels;
    for (int level = 0; level <= int(cpuSimdLevel()); ++level) levels.push_back(SimdLevel(level));
    return levels;
}

// A test parameterised by SIMD level: runs with that level active, restores the previous one after.
class SimdLevelTest : public ::testing::TestWithParam<SimdLevel> {
  protected:
    void SetUp() override {
        original_ = activeSimdLevel();
        setSimdLevel(GetParam());
    }
    void TearDown() override { setSimdLevel(original_); }

  private:
    SimdLevel original_ = SimdLevel::Scalar;
};

inline std::string simdTestName(const ::testing::TestParamInfo<SimdLevel>& info) {
    return simdLevelName(info.param);
}

}  // namespace dejag::testing

namespace dejag {
inline void PrintTo(SimdLevel level, std::ostream* out) {
    *out << simdLevelName(level);
}
}  // namespace dejag
