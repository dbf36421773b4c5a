#include "app/cli.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <regex>
#include <sstream>
#include <string_view>

#include "base/error.h"
#include "base/files.h"
#include "base/simd.h"
#include "base/thread_pool.h"

namespace dejag::cli {

void addRuntimeOptions(CLI::App* command, RuntimeOptions& options) {
    command->add_option("--threads", options.threads, "worker threads (default: DEJAG_THREADS or all cores)")
        ->check(CLI::Range(1, 1024));
    command->add_option("--simd", options.simd, "force a SIMD path: scalar, avx2 or avx512 (default: best)")
        ->check(CLI::IsMember({"scalar", "avx2", "avx512"}));
}

void applyRuntimeOptions(const RuntimeOptions& options) {
    if (!options.simd.empty()) setSimdLevel(*parseSimdLevel(options.simd));
    setThreadCount(options.threads);
}

void guardNumericOptions(CLI::App& app) {
    // CLI11 parses "nan" and "inf" into a float and lets them through a Range (every comparison with NaN
    // is false), and strtoull turns "-1" into 2^64 - 1: both are refused here, for every option at once.
    static const CLI::Validator finite(
        [](std::string& text) -> std::string {
            char* end = nullptr;
            const double value = std::strtod(text.c_str(), &end);
            if (end == text.c_str() || *end != '\0') return "'" + text + "' is not a number";
            return std::isfinite(value) ? std::string() : "'" + text + "' is not a finite number";
        },
        "", "finite");
    static const CLI::Validator unsignedNumber(
        [](std::string& text) -> std::string {
            const size_t first = text.find_first_not_of(" \t");
            return first != std::string::npos && text[first] == '-' ? "'" + text + "' is negative"
                                                                    : std::string();
        },
        "", "unsigned");
    for (CLI::Option* option : app.get_options()) {
        const std::string type = option->get_type_name();
        if (type.rfind("FLOAT", 0) == 0)
            option->check(finite);
        else if (type.rfind("UINT", 0) == 0)
            option->check(unsignedNumber);
    }
    for (CLI::App* command : app.get_subcommands([](const CLI::App*) { return true; }))
        guardNumericOptions(*command);
}

namespace {
// An example for each command, by its path below `dejag`.
const std::map<std::string, std::string>& examples() {
    static const std::map<std::string, std::string> table = {
        {"", "dejag filter --method smaa frame.png smooth.png"},
        {"render", "dejag render --scene atrium --size 1280x720 --truth 64 --out out/atrium"},
        {"data", "dejag data generate --count 200 --out out/dataset"},
        {"data generate",
         "dejag data generate --families shapes,text --count 100 --size 256x256 --out out/small"},
        {"data verify", "dejag data verify out/dataset"},
        {"data stats", "dejag data stats --json out/dataset"},
        {"train", "dejag train --data out/dataset --out runs/mine --arch kpn:8x3 --steps 6000"},
        {"train export", "dejag train export runs/mine models/mine.safetensors"},
        {"filter", "dejag filter --method cnn --model models/dejag-guided.safetensors frame.exr smooth.png"},
        {"metrics", "dejag metrics --json truth.exr smooth.exr"},
        {"export", "dejag export --onnx dejag-fast dejag-fast.onnx"},
        {"view", "dejag view --scene atrium --method cnn --compare fxaa"},
        {"bench", "dejag bench filter --threads 2"},
        {"bench render", "dejag bench render --quick"},
        {"bench filter", "dejag bench filter --threads 2 --size 1920x1080"},
        {"bench glsl", "dejag bench glsl --size 960x540 --methods fxaa,smaa,taa-hq"},
        {"bench collective",
         "mpirun -np 2 dejag-mpi bench collective --model dejag-temporal --step-seconds 0.34"},
        {"bench stability", "dejag bench stability --configs 200"},
        {"bench taa", "dejag bench taa --frames 32 --no-ghosting"},
        {"bench texture", "dejag bench texture --cases checker,normal-map --out out/texture"},
        {"bench quality", "dejag bench quality --data out/dataset --no-1080p"},
        {"bench reach", "dejag bench reach --size 1280x720 --scenes atrium pipe"},
        {"bench metrics", "dejag bench metrics --thread-counts 1,2"},
        {"demo", "dejag demo --scenes atrium,flowers --size 640x360"},
        {"completion", "dejag completion bash > ~/.local/share/bash-completion/completions/dejag"},
    };
    return table;
}

void finishHelp(CLI::App& command, const std::string& path) {
    // (bench nn hands --help to dejag-bench-nn; a hidden command, one with no group, has no help to finish)
    if (command.get_help_ptr() != nullptr && (path.empty() || !command.get_group().empty())) {
        command.set_help_flag("-h,--help", "print this help message and exit");
        const auto example = examples().find(path);
        if (example == examples().end()) throw Error("internal: no --help example for 'dejag " + path + "'");
        const std::string footer = command.get_footer();
        command.footer(footer + (footer.empty() ? "" : "\n") + "Example: " + example->second);
    }
    for (CLI::App* sub : command.get_subcommands([](const CLI::App*) { return true; }))
        finishHelp(*sub, path.empty() ? sub->get_name() : path + " " + sub->get_name());
}
}  // namespace

void finishHelp(CLI::App& app) {
    finishHelp(app, "");
}

std::string shippedModelPath(const std::string& name) {
    namespace fs = std::filesystem;
    std::error_code error;
    // A bare name (no folder, no extension) that is not a file here names a shipped model.
    std::string path = name;
    if (!name.empty() && fs::path(name).parent_path().empty() && !fs::path(name).has_extension() &&
        !fs::exists(name, error))
        path = "models/" + name + ".safetensors";
    const fs::path given(path);
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

StandardStreams::~StandardStreams() {
    if (folder_.empty()) return;
    std::error_code error;
    std::filesystem::remove_all(folder_, error);
}

const std::string& StandardStreams::folder() {
    if (folder_.empty()) {
        const char* base = std::getenv("TMPDIR");
        std::string pattern = std::string(base && *base ? base : "/tmp") + "/dejag-stdio-XXXXXX";
        if (!mkdtemp(pattern.data()))
            throw Error("cannot make a temporary folder for '-': " + systemErrorText(errno));
        folder_ = pattern;
    }
    return folder_;
}

std::string StandardStreams::input(const std::string& path) {
    if (path != "-") return path;
    std::string bytes;
    char buffer[1 << 16];
    size_t got;
    while ((got = std::fread(buffer, 1, sizeof buffer, stdin)) > 0) bytes.append(buffer, got);
    if (std::ferror(stdin)) throw Error("cannot read standard input: " + systemErrorText(errno));
    auto starts = [&](std::string_view magic) { return bytes.compare(0, magic.size(), magic) == 0; };
    std::string extension;
    if (starts("\x89PNG\r\n\x1a\n"))
        extension = ".png";
    else if (starts("\xff\xd8\xff"))
        extension = ".jpg";
    else if (starts(std::string_view("II*\0", 4)) || starts(std::string_view("MM\0*", 4)))
        extension = ".tif";
    else if (starts("\x76\x2f\x31\x01"))
        extension = ".exr";
    else
        throw Error(bytes.empty() ? std::string("standard input ('-') is empty")
                                  : "standard input ('-') is not a PNG, JPEG, TIFF or OpenEXR image");
    const std::string file = folder() + "/stdin" + extension;
    writeBytesAtomically(file, bytes);
    return file;
}

std::string StandardStreams::output(const std::string& path, const std::string& extension) {
    if (path != "-") return path;
    output_ = folder() + "/stdout" + extension;
    return output_;
}

void StandardStreams::finish() {
    if (output_.empty()) return;
    std::ifstream in(output_, std::ios::binary);
    if (!in) throw Error("nothing was written for standard output ('-')");
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (std::fwrite(bytes.data(), 1, bytes.size(), stdout) != bytes.size() || std::fflush(stdout) != 0)
        throw Error("cannot write standard output: " + systemErrorText(errno));
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
