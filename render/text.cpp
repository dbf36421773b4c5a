// Text for the viewer's overlay: see render/text.h.
#include "render/text.h"

#include <algorithm>

#include "render/freetype.h"

namespace dejag::render {

struct TextRenderer::Impl {
    FreeType freetype;
    Face face{freetype.library, {"/usr/share/fonts/truetype/dejavu/DejaVuSansMono.ttf", "fonts-dejavu-core"}};
};

TextRenderer::TextRenderer(int pixelSize) : impl_(std::make_unique<Impl>()), size_(pixelSize) {
    if (pixelSize < 4 || pixelSize > 256) throw Error("text size must be 4..256 pixels");
    FT_Set_Pixel_Sizes(impl_->face.face, 0, FT_UInt(pixelSize));
}

TextRenderer::~TextRenderer() = default;

TextBitmap TextRenderer::render(const std::vector<std::string>& lines) const {
    FT_Face face = impl_->face.face;
    const int lineHeight = int(face->size->metrics.height >> 6),
              ascent = int(face->size->metrics.ascender >> 6);
    const int margin = lineHeight / 2;
    // Widths first (a monospaced face: the advance of each glyph).
    int width = 0;
    for (const std::string& line : lines) {
        int pen = 0;
        for (const char ch : line)
            if (uint8_t(ch) >= 32 && uint8_t(ch) < 127 && !FT_Load_Char(face, FT_ULong(ch), FT_LOAD_DEFAULT))
                pen += int(face->glyph->advance.x >> 6);
        width = std::max(width, pen);
    }
    TextBitmap t;
    t.width = width + 2 * margin, t.height = int(lines.size()) * lineHeight + 2 * margin;
    t.coverage.assign(size_t(t.width) * size_t(t.height), 0);
    for (size_t l = 0; l < lines.size(); ++l) {
        int pen = margin;
        const int baseline = margin + int(l) * lineHeight + ascent;
        for (const char ch : lines[l]) {
            if (uint8_t(ch) < 32 || uint8_t(ch) >= 127 || FT_Load_Char(face, FT_ULong(ch), FT_LOAD_RENDER))
                continue;
            const FT_Bitmap& b = face->glyph->bitmap;
            const int left = pen + face->glyph->bitmap_left, top = baseline - face->glyph->bitmap_top;
            for (int r = 0; r < int(b.rows); ++r)
                for (int c = 0; c < int(b.width); ++c) {
                    const int x = left + c, y = top + r;
                    if (x < 0 || y < 0 || x >= t.width || y >= t.height) continue;
                    uint8_t& p = t.coverage[size_t(y) * size_t(t.width) + size_t(x)];
                    p = std::max(p, b.buffer[r * b.pitch + c]);
                }
            pen += int(face->glyph->advance.x >> 6);
        }
    }
    return t;
}

}  // namespace dejag::render
