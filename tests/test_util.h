// Helpers shared by the test suites.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include <ostream>
#include <vector>

#include "base/simd.h"

namespace dejag::testing {

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
