// dejag/render: lines of text drawn with FreeType into a coverage bitmap, what dejag view's overlay shows.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace dejag::render {

// 8-bit coverage, row 0 at the top.
struct TextBitmap {
    int width = 0, height = 0;
    std::vector<uint8_t> coverage;
};

class TextRenderer {
  public:
    // DejaVu Sans Mono at `pixelSize` pixels; throws dejag::Error naming the font and its package if it
    // is missing.
    explicit TextRenderer(int pixelSize);
    ~TextRenderer();
    TextRenderer(const TextRenderer&) = delete;
    TextRenderer& operator=(const TextRenderer&) = delete;
    // The lines one under another (ASCII; other characters are skipped), with a margin of half a line.
    TextBitmap render(const std::vector<std::string>& lines) const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    int size_ = 0;
};

}  // namespace dejag::render
