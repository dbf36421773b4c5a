// dejag/fuzz: helpers shared by the libFuzzer targets (make fuzz).
//
// The loaders under test read files, so each input is written to a file in a private folder under
// /dev/shm (memory, not disk) first. A target passes when dejag code either succeeds or throws: any
// crash, hang, leak or sanitizer report (ASan + UBSan are on) is a finding.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

namespace dejag::fuzz {

inline std::filesystem::path scratchFolder() {
    static const std::filesystem::path folder = [] {
        std::filesystem::path p =
            std::filesystem::path("/dev/shm") / ("dejag-fuzz-" + std::to_string(getpid()));
        std::filesystem::create_directories(p);
        return p;
    }();
    return folder;
}

inline std::string writeScratchFile(const std::string& name, const uint8_t* data, size_t size) {
    const std::filesystem::path path = scratchFolder() / name;
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
    return path.string();
}

}  // namespace dejag::fuzz
