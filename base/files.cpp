#include "base/files.h"

#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "base/error.h"

namespace dejag {
namespace fs = std::filesystem;

namespace {

std::string temporaryNameFor(const fs::path& path) {
    static std::atomic<unsigned> counter{0};
    fs::path parent = path.parent_path();
    std::string name = "." + path.stem().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                       std::to_string(counter.fetch_add(1)) + path.extension().string();
    return (parent / name).string();
}

}  // namespace

void writeFileAtomically(const std::string& path, const std::function<void(const std::string&)>& write) {
    fs::path target(path);
    fs::path parent = target.parent_path().empty() ? fs::path(".") : target.parent_path();
    std::error_code ec;
    if (!fs::is_directory(parent, ec))
        throw Error("cannot write '" + path + "': folder '" + parent.string() + "' does not exist");
    if (fs::is_directory(target, ec)) throw Error("cannot write '" + path + "': it is a folder");
    std::string temporary = temporaryNameFor(target);
    try {
        write(temporary);
    } catch (...) {
        fs::remove(temporary, ec);
        throw;
    }
    fs::rename(temporary, target, ec);
    if (ec) {
        std::error_code ignored;
        fs::remove(temporary, ignored);
        throw Error("cannot write '" + path + "': " + ec.message());
    }
}

void writeTextFileAtomically(const std::string& path, const std::string& text) {
    writeFileAtomically(path, [&](const std::string& temporary) {
        std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
        if (!out) throw Error("cannot write '" + path + "': " + std::strerror(errno));
        out.write(text.data(), std::streamsize(text.size()));
        out.flush();
        if (!out) throw Error("cannot write '" + path + "': write failed");
    });
}

void requireReadableFile(const std::string& path) {
    std::error_code ec;
    fs::file_status status = fs::status(path, ec);
    if (!fs::exists(status)) throw Error("cannot read '" + path + "': no such file");
    if (fs::is_directory(status)) throw Error("cannot read '" + path + "': it is a folder, not a file");
    if (::access(path.c_str(), R_OK) != 0) throw Error("cannot read '" + path + "': " + std::strerror(errno));
}

}  // namespace dejag
