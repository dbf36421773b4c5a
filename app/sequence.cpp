#include "app/sequence.h"

#include <algorithm>
#include <cctype>
#include <cstdio>

#include "base/error.h"

namespace dejag::cli {

namespace fs = std::filesystem;

bool isImageFile(const fs::path& path) {
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tif" || ext == ".tiff" ||
           ext == ".exr";
}

// "frame_%04d.png" -> the path of frame i (isPattern has checked the pattern).
std::string formatPattern(const std::string& pattern, int index) {
    char text[4096];
    const int n = std::snprintf(text, sizeof text, pattern.c_str(), index);
    if (n < 0 || size_t(n) >= sizeof text)
        throw Error("'" + pattern + "': the file name it gives is too long");
    return text;
}
// True for a printf-style sequence pattern: one field %d, %Nd or %0Nd with N at most 2 digits.
bool isPattern(const std::string& path) {
    const size_t percent = path.find('%');
    if (percent == std::string::npos) return false;
    const std::string bad = "'" + path + "': a sequence pattern holds one integer field such as %04d";
    size_t i = percent + 1;
    if (i < path.size() && path[i] == '0') ++i;
    const size_t digits = i;
    while (i < path.size() && std::isdigit(static_cast<unsigned char>(path[i]))) ++i;
    if (i - digits > 2) throw Error(bad + " (a field at most 99 digits wide)");
    if (i >= path.size() || path[i] != 'd' || path.find('%', i) != std::string::npos) throw Error(bad);
    if (fs::path(path).parent_path().string().find('%') != std::string::npos)
        throw Error(bad + " in the file name, not in a folder");
    return true;
}

// The frame numbers of a pattern that exist, in order: the files of its folder whose names it gives.
std::vector<int> sequenceFrames(const std::string& pattern) {
    const fs::path folder =
        fs::path(pattern).parent_path().empty() ? fs::path(".") : fs::path(pattern).parent_path();
    const std::string name = fs::path(pattern).filename().string();
    const size_t percent = name.find('%'), field = name.find('d', percent);
    const std::string prefix = name.substr(0, percent), suffix = name.substr(field + 1);
    std::vector<int> frames;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(folder, ec)) {
        const std::string file = entry.path().filename().string();
        if (file.size() <= prefix.size() + suffix.size() || file.compare(0, prefix.size(), prefix) != 0 ||
            file.compare(file.size() - suffix.size(), suffix.size(), suffix) != 0)
            continue;
        const std::string number = file.substr(prefix.size(), file.size() - prefix.size() - suffix.size());
        if (number.size() > 9 ||
            !std::all_of(number.begin(), number.end(), [](unsigned char c) { return std::isdigit(c); }))
            continue;
        const int index = std::stoi(number);
        if (formatPattern(name, index) == file) frames.push_back(index);
    }
    std::sort(frames.begin(), frames.end());
    return frames;
}

// The number at the end of a file's stem ("frame_0012.exr" -> 12), or -1.
long trailingNumber(const fs::path& path) {
    const std::string stem = path.stem().string();
    size_t digits = stem.size();
    while (digits > 0 && std::isdigit(static_cast<unsigned char>(stem[digits - 1]))) --digits;
    if (digits == stem.size() || stem.size() - digits > 9) return -1;
    return std::stol(stem.substr(digits));
}

// A folder written by dejag render: it holds render.json next to its frame_NNNN.exr files.
bool isRenderFolder(const fs::path& folder) {
    std::error_code ec;
    return fs::is_regular_file(folder / "render.json", ec);
}

std::vector<SequenceFrame> listSequence(const std::string& input) {
    std::vector<SequenceFrame> frames;
    if (isPattern(input)) {
        const std::vector<int> numbers = sequenceFrames(input);
        if (numbers.empty()) throw Error("no frame matches '" + input + "'");
        for (size_t k = 1; k < numbers.size(); ++k)
            if (numbers[k] != numbers[k - 1] + 1)
                throw Error("'" + input + "' has a gap: frame " + std::to_string(numbers[k - 1] + 1) +
                            " is missing between " + formatPattern(input, numbers[k - 1]) + " and " +
                            formatPattern(input, numbers[k]) + " (a run of frames is taken whole)");
        for (int i : numbers) frames.push_back({formatPattern(input, i), i});
        return frames;
    }
    if (!fs::is_directory(input)) throw Error("'" + input + "' is neither a folder nor a sequence pattern");
    const bool rendered = isRenderFolder(input);
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(input)) {
        const std::string name = entry.path().filename().string();
        if (!entry.is_regular_file() || !isImageFile(entry.path()) || name.front() == '.') continue;
        if (rendered && (name.rfind("frame_", 0) != 0 || entry.path().extension() != ".exr")) continue;
        files.push_back(entry.path());
    }
    std::sort(files.begin(), files.end());
    if (files.empty())
        throw Error(rendered ? "'" + input + "' holds no frame_NNNN.exr"
                             : "folder '" + input + "' holds no PNG, JPEG, TIFF or EXR image");
    for (const fs::path& f : files) frames.push_back({f.string(), trailingNumber(f)});
    return frames;
}

bool isSequence(const std::string& path) {
    return isPattern(path) || fs::is_directory(path);
}

}  // namespace dejag::cli
