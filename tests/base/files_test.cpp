#include "base/files.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "base/error.h"
#include "tests/test_util.h"

namespace dejag {
namespace {

std::string readAll(const std::string& path) {
    std::ifstream in(path);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
}

size_t filesIn(const std::filesystem::path& folder) {
    return size_t(
        std::distance(std::filesystem::directory_iterator(folder), std::filesystem::directory_iterator()));
}

TEST(Files, AtomicWriteReplacesTheTarget) {
    testing::TempDir dir;
    writeTextFileAtomically(dir.file("a.txt"), "first");
    writeTextFileAtomically(dir.file("a.txt"), "second");
    EXPECT_EQ(readAll(dir.file("a.txt")), "second");
    EXPECT_EQ(filesIn(dir.path()), 1u) << "a temporary file was left behind";
}

TEST(Files, FailedWriteKeepsTheOldFileAndLeavesNoTemporary) {
    testing::TempDir dir;
    writeTextFileAtomically(dir.file("a.txt"), "precious");
    EXPECT_THROW(
        {
            AtomicFile file(dir.file("a.txt"));
            file.write("half");
            throw Error("disk full");
        },
        Error);
    EXPECT_EQ(readAll(dir.file("a.txt")), "precious");
    EXPECT_EQ(filesIn(dir.path()), 1u);
}

TEST(Files, MissingFolderIsAClearError) {
    testing::TempDir dir;
    try {
        writeTextFileAtomically(dir.file("no/such/folder/a.txt"), "x");
        FAIL() << "expected an error";
    } catch (const Error& error) {
        EXPECT_NE(std::string(error.what()).find("does not exist"), std::string::npos) << error.what();
    }
}

TEST(Files, RequireReadableFile) {
    testing::TempDir dir;
    EXPECT_THROW(requireReadableFile(dir.file("missing.png")), Error);
    EXPECT_THROW(requireReadableFile(dir.path().string()), Error);
    writeTextFileAtomically(dir.file("ok.txt"), "x");
    EXPECT_NO_THROW(requireReadableFile(dir.file("ok.txt")));
}

}  // namespace
}  // namespace dejag
