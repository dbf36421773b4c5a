// Invariants of the repository itself: a clone holds everything its code and docs cite.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

// The tracked text files: sources, scripts, docs, model cards and the top-level files.
std::vector<fs::path> repositoryTextFiles() {
    const fs::path root = DEJAG_SOURCE_DIR;
    std::vector<fs::path> files;
    for (const char* top : {"README.md", "Makefile", "CMakeLists.txt"})
        if (fs::exists(root / top)) files.push_back(root / top);
    for (const char* folder : {"app", "base", "bench", "data", "docs", "fuzz", "infer", "models", "nn",
                               "render", "scripts", "tests", "train", ".ci"}) {
        if (!fs::exists(root / folder)) continue;
        for (const fs::directory_entry& entry : fs::recursive_directory_iterator(root / folder)) {
            if (!entry.is_regular_file()) continue;
            const std::string ext = entry.path().extension().string();
            if (ext == ".cpp" || ext == ".h" || ext == ".md" || ext == ".py" || ext == ".txt" ||
                ext == ".json" || ext == ".cmake" || ext == "" || ext == ".sh" || ext == ".html")
                files.push_back(entry.path());
        }
    }
    return files;
}

std::string slurp(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

}  // namespace

// Nothing names a file outside the repository (a sibling folder of specs or papers that a clone lacks),
// and every docs/ page that is cited exists.
TEST(Repository, CitesOnlyFilesItHolds) {
    const fs::path root = DEJAG_SOURCE_DIR;
    // Spelled in pieces so that this file does not match itself.
    const std::regex outside(std::string("\\.\\./") +
                             "shared|(^|[^a-zA-Z0-9_/.])(spec|papers)/[A-Za-z0-9_-]+\\.(md|txt)");
    const std::regex cited("docs/([A-Za-z0-9_/-]+\\.md)");
    const std::vector<fs::path> files = repositoryTextFiles();
    ASSERT_GT(files.size(), 100u) << "the source tree was not found at " << root;
    for (const fs::path& file : files) {
        if (fs::file_size(file) > (4u << 20)) continue;  // data, not text that cites
        const std::string text = slurp(file);
        std::smatch m;
        if (std::regex_search(text, m, outside))
            ADD_FAILURE() << fs::relative(file, root).string() << " refers to '" << m.str()
                          << "', which is not in the repository";
        for (auto it = std::sregex_iterator(text.begin(), text.end(), cited); it != std::sregex_iterator();
             ++it)
            EXPECT_TRUE(fs::exists(root / "docs" / (*it)[1].str()))
                << fs::relative(file, root).string() << " cites " << (*it)[0].str()
                << ", which does not exist";
    }
}
