#include "app/cli.h"

#include <filesystem>
#include <regex>
#include <sstream>

#include "base/error.h"
#include "base/simd.h"
#include "base/thread_pool.h"

namespace dejag::cli {

void addRuntimeOptions(CLI::App* command, RuntimeOptions& options) {
    command->add_option("--threads", options.threads, "Worker threads (default: DEJAG_THREADS or all cores)")
        ->check(CLI::Range(1, 1024));
    command->add_option("--simd", options.simd, "Force a SIMD path: scalar, avx2 or avx512 (default: best)")
        ->check(CLI::IsMember({"scalar", "avx2", "avx512"}));
}

void applyRuntimeOptions(const RuntimeOptions& options) {
    if (!options.simd.empty()) setSimdLevel(*parseSimdLevel(options.simd));
    setThreadCount(options.threads);
}

std::string shippedModelPath(const std::string& path) {
    namespace fs = std::filesystem;
    const fs::path given(path);
    std::error_code error;
    if (given.is_absolute() || given.empty() || *given.begin() != "models" || fs::exists(given, error))
        return path;
    const fs::path binary = fs::read_symlink("/proc/self/exe", error);
    if (error) return path;
    const fs::path folder = binary.parent_path();
    for (const fs::path& root : {folder / ".." / "..", folder / ".." / "share" / "dejag"}) {
        const fs::path candidate = (root / given).lexically_normal();
        if (fs::is_regular_file(candidate, error)) return candidate.string();
    }
    return path;
}

std::vector<std::string> shippedModelPaths(const std::vector<std::string>& paths) {
    std::vector<std::string> found;
    for (const std::string& path : paths) found.push_back(shippedModelPath(path));
    return found;
}

Size parseSize(const std::string& text, const std::string& what) {
    static const std::regex pattern(R"(^(\d{1,6})[xX](\d{1,6})$)");
    std::smatch match;
    if (!std::regex_match(text, match, pattern))
        throw Error(what + " '" + text + "' is not WIDTHxHEIGHT (e.g. 1920x1080)");
    Size size{std::stoi(match[1]), std::stoi(match[2])};
    if (size.width < 1 || size.height < 1 || size.width > 16384 || size.height > 16384)
        throw Error(what + " '" + text + "' must have sides from 1 to 16384");
    return size;
}

std::string& invocation() {
    static std::string line;
    return line;
}

std::vector<std::string> splitList(const std::string& text) {
    std::vector<std::string> items;
    std::stringstream stream(text);
    std::string item;
    while (std::getline(stream, item, ','))
        if (!item.empty()) items.push_back(item);
    return items;
}

}  // namespace dejag::cli
