// dejag/render (internal): FreeType's library and a font face as RAII objects, and a font file with the
// Debian package that installs it (so a missing one is an error naming the package).
#pragma once

#include <ft2build.h>
#include FT_FREETYPE_H

#include <filesystem>
#include <string>

#include "base/error.h"

namespace dejag::render {

struct FontFile {
    const char* path;
    const char* package;
};

struct FreeType {
    FT_Library library = nullptr;
    FreeType() {
        if (FT_Init_FreeType(&library)) throw Error("FreeType failed to initialise");
    }
    ~FreeType() { FT_Done_FreeType(library); }
    FreeType(const FreeType&) = delete;
    FreeType& operator=(const FreeType&) = delete;
};

struct Face {
    FT_Face face = nullptr;
    Face(FT_Library library, const FontFile& file) {
        if (!std::filesystem::exists(file.path))
            throw Error(std::string("font ") + file.path + " is missing (Debian package " + file.package +
                        "; scripts/install-deps installs it)");
        if (FT_New_Face(library, file.path, 0, &face))
            throw Error(std::string("font ") + file.path + " cannot be read by FreeType");
    }
    ~Face() { FT_Done_Face(face); }
    Face(const Face&) = delete;
    Face& operator=(const Face&) = delete;
};

}  // namespace dejag::render
