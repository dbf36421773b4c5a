#include "render/vector_art.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>

#include "base/error.h"
#include "base/random.h"
#include "render/freetype.h"

namespace dejag::render {

namespace {

class Draw {
  public:
    explicit Draw(uint64_t seed) : state_(splitMix64(seed ^ 0x2D2D2Dull)) {}
    double uniform(double low = 0, double high = 1) {
        state_ += 0x9E3779B97F4A7C15ull;
        return unitInterval(splitMix64(state_), low, high);
    }
    double logUniform(double low, double high) { return std::exp(uniform(std::log(low), std::log(high))); }
    int below(int n) { return std::min(n - 1, int(uniform(0, n))); }
    bool chance(double p) { return uniform() < p; }
    // A colour; a third of them near black or white (the contrast of diagrams and type).
    Vec3 colour() {
        if (chance(1.0 / 3)) {
            const double v = chance(0.5) ? uniform(0.0, 0.08) : uniform(0.9, 1.0);
            return {v, v, v};
        }
        return {uniform(0.03, 0.97), uniform(0.03, 0.97), uniform(0.03, 0.97)};
    }
    // An angle: 40 % within 6 degrees of horizontal or vertical (the long, nearly axis-aligned edges of
    // user interfaces and maps), the rest anywhere.
    double angle() {
        if (chance(0.4)) return below(4) * kPi / 2 + uniform(-6, 6) * kPi / 180;
        return uniform(0, 2 * kPi);
    }

  private:
    uint64_t state_;
};

// The fixed camera of both scenes: looking straight at the plane z = 0 from z = 5 with a 40 degree
// field of view, so a pixel of a 256-row frame is kPixel world units there.
constexpr double kEye = 5.0, kFovDegrees = 40.0;
const double kViewHeight = 2 * kEye * std::tan(kFovDegrees / 2 * kPi / 180);
const double kPixel = kViewHeight / 256;

Vertex flatVertex(double x, double y, double z, double u, double v) {
    return Vertex{{float(x), float(y), float(z)}, {0, 0, 1}, {float(u), float(v)}};
}

// A stroke of `width` along a polyline (mitred joins, the mitre limited to 4 widths), at depth z.
Mesh strokeMesh(const std::vector<Vec3>& points, double width, bool closed, double z) {
    Mesh m;
    const size_t n = points.size();
    if (n < 2) return m;
    auto segmentNormal = [&](size_t a, size_t b) {
        const Vec3 d = normalize(points[b] - points[a]);
        return Vec3{-d.y, d.x, 0};
    };
    for (size_t i = 0; i < n; ++i) {
        const bool hasPrevious = i > 0 || closed, hasNext = i + 1 < n || closed;
        const Vec3 before = hasPrevious ? segmentNormal(i == 0 ? n - 1 : i - 1, i) : segmentNormal(i, i + 1);
        const Vec3 after = hasNext ? segmentNormal(i, (i + 1) % n) : before;
        Vec3 normal = normalize(before + after);
        if (!std::isfinite(normal.x)) normal = after;  // a reversal: square it off
        const double scale = 1.0 / std::max(0.25, normal.x * after.x + normal.y * after.y);
        const Vec3 offset = normal * (0.5 * width * scale);
        const double u = double(i) / double(n - 1);
        m.vertices.push_back(flatVertex(points[i].x + offset.x, points[i].y + offset.y, z, u, 0));
        m.vertices.push_back(flatVertex(points[i].x - offset.x, points[i].y - offset.y, z, u, 1));
    }
    const size_t segments = closed ? n : n - 1;
    for (size_t i = 0; i < segments; ++i) {
        const uint32_t a = uint32_t(2 * i), b = uint32_t(2 * ((i + 1) % n));
        m.indices.insert(m.indices.end(), {a, a + 1, b + 1, a, b + 1, b});
    }
    return m;
}

// A filled polygon, star-shaped about `centre` (a fan of triangles from it), at depth z.
Mesh fanMesh(const Vec3& centre, const std::vector<Vec3>& ring, double z) {
    Mesh m;
    m.vertices.push_back(flatVertex(centre.x, centre.y, z, 0.5, 0.5));
    for (const Vec3& p : ring) m.vertices.push_back(flatVertex(p.x, p.y, z, 0, 0));
    const uint32_t n = uint32_t(ring.size());
    for (uint32_t i = 0; i < n; ++i) m.indices.insert(m.indices.end(), {0, 1 + i, 1 + (i + 1) % n});
    return m;
}

Vec3 point(Draw& draw, double margin = 1.2) {
    const double half = kViewHeight / 2 * margin;
    return {draw.uniform(-half * 1.5, half * 1.5), draw.uniform(-half, half), 0};
}

Material flat(const Vec3& colour) {
    Material m;
    m.colour = colour, m.lit = false;
    return m;
}

}  // namespace

void vectorArtScene(Scene& s, const SceneOptions& o) {
    Draw draw(o.seed);
    s.background = draw.colour();
    // A backdrop wider than any framing (16:9 and the dataset's camera turns), slightly behind.
    s.addObject("page", s.addMesh(makeQuad(14, 8)), flat(s.background), [](double) {
        return Mat4::translation({0, 0, -0.01});
    });
    const int count = 12 + draw.below(24);
    for (int i = 0; i < count; ++i) {
        const double z = 0.002 * (i + 1);
        const Vec3 colour = draw.colour();
        // Widths in pixels of a 256-row frame, log-uniform: from a quarter of a pixel (a hairline that
        // 1 sample a pixel breaks into dashes) to several.
        const double width = draw.logUniform(0.25, 5.0) * kPixel;
        Mesh mesh;
        std::string name;
        switch (draw.below(7)) {
            case 0: {  // straight lines, a few parallel ones at a random spacing
                name = "lines";
                const Vec3 a = point(draw);
                const double angle = draw.angle();
                const Vec3 d{std::cos(angle), std::sin(angle), 0}, across{-d.y, d.x, 0};
                const double length = draw.logUniform(0.3, 6.0), spacing = draw.logUniform(1.5, 12) * kPixel;
                const int copies = draw.chance(0.5) ? 1 : 2 + draw.below(12);
                for (int k = 0; k < copies; ++k) {
                    const Vec3 start = a + across * (k * spacing);
                    mesh.append(strokeMesh({start, start + d * length}, width, false, z));
                }
                break;
            }
            case 1: {  // a fan of spokes from a centre over a sector
                name = "fan";
                const Vec3 c = point(draw);
                const int spokes = 8 + draw.below(40);
                const double start = draw.uniform(0, 2 * kPi), sector = draw.uniform(0.3, 2 * kPi);
                const double inner = draw.uniform(0, 0.3), outer = inner + draw.uniform(0.4, 2.5);
                for (int k = 0; k < spokes; ++k) {
                    const double a = start + sector * k / spokes;
                    const Vec3 d{std::cos(a), std::sin(a), 0};
                    mesh.append(
                        strokeMesh({c + d * inner, c + d * outer}, std::min(width, 1.5 * kPixel), false, z));
                }
                break;
            }
            case 2: {  // a filled polygon: a rectangle, a regular polygon or a star
                name = "polygon";
                const Vec3 c = point(draw);
                const double r = draw.logUniform(0.05, 1.2), turn = draw.angle();
                const int kind = draw.below(3), corners = 3 + draw.below(kind == 2 ? 6 : 8);
                std::vector<Vec3> ring;
                if (kind == 0) {
                    const double w = r * draw.uniform(0.3, 2), h = r * draw.uniform(0.3, 2);
                    for (const auto& [x, y] : {std::pair{-w, -h}, {w, -h}, {w, h}, {-w, h}})
                        ring.push_back(c + Vec3{x * std::cos(turn) - y * std::sin(turn),
                                                x * std::sin(turn) + y * std::cos(turn), 0});
                } else {
                    const int points = kind == 2 ? 2 * corners : corners;
                    for (int k = 0; k < points; ++k) {
                        const double a = turn + 2 * kPi * k / points;
                        const double radius = kind == 2 && k % 2 ? r * draw.uniform(0.3, 0.6) : r;
                        ring.push_back(c + Vec3{radius * std::cos(a), radius * std::sin(a), 0});
                    }
                }
                mesh = fanMesh(c, ring, z);
                if (draw.chance(0.4)) {  // an outline in another colour
                    std::vector<Vec3> outline = ring;
                    s.addObject("outline", s.addMesh(strokeMesh(outline, width, true, z + 0.001)),
                                flat(draw.colour()));
                }
                break;
            }
            case 3: {  // a cubic Bezier curve
                name = "curve";
                const Vec3 p0 = point(draw), p1 = point(draw), p2 = point(draw), p3 = point(draw);
                std::vector<Vec3> points;
                for (int k = 0; k <= 96; ++k) {
                    const double t = k / 96.0, u = 1 - t;
                    points.push_back(p0 * (u * u * u) + p1 * (3 * u * u * t) + p2 * (3 * u * t * t) +
                                     p3 * (t * t * t));
                }
                mesh = strokeMesh(points, width, false, z);
                break;
            }
            case 4: {  // rings: circle or ellipse outlines, sometimes concentric
                name = "rings";
                const Vec3 c = point(draw);
                const double r = draw.logUniform(0.04, 1.5),
                             squash = draw.chance(0.5) ? 1 : draw.uniform(0.3, 1);
                const double turn = draw.uniform(0, kPi);
                const int rings = draw.chance(0.6) ? 1 : 2 + draw.below(6);
                const double step = draw.logUniform(2, 15) * kPixel;
                for (int k = 0; k < rings; ++k) {
                    std::vector<Vec3> points;
                    const double radius = r + k * step;
                    for (int j = 0; j < 160; ++j) {
                        const double a = 2 * kPi * j / 160, x = radius * std::cos(a),
                                     y = radius * squash * std::sin(a);
                        points.push_back(c + Vec3{x * std::cos(turn) - y * std::sin(turn),
                                                  x * std::sin(turn) + y * std::cos(turn), 0});
                    }
                    mesh.append(strokeMesh(points, width, true, z));
                }
                break;
            }
            case 5: {  // a road of a map: a smooth random walk, a dark casing under a lighter fill
                name = "road";
                std::vector<Vec3> points{point(draw)};
                double heading = draw.angle(), turnRate = 0;
                const double step = draw.uniform(0.05, 0.15);
                const int steps = 20 + draw.below(40);
                for (int k = 0; k < steps; ++k) {
                    turnRate = 0.8 * turnRate + draw.uniform(-0.12, 0.12);
                    heading += turnRate;
                    points.push_back(points.back() + Vec3{std::cos(heading), std::sin(heading), 0} * step);
                }
                const double casing = draw.logUniform(2, 10) * kPixel;
                mesh = strokeMesh(points, casing, false, z);
                s.addObject("road fill",
                            s.addMesh(strokeMesh(points, casing * draw.uniform(0.4, 0.75), false, z + 0.001)),
                            flat(draw.colour()));
                break;
            }
            default: {  // hatching: a patch of parallel thin lines, as in a map's area fill or an engraving
                name = "hatching";
                const Vec3 c = point(draw);
                const double angle = draw.angle(), size = draw.logUniform(0.2, 1.5);
                const double spacing = draw.logUniform(1.2, 6) * kPixel;
                const Vec3 d{std::cos(angle), std::sin(angle), 0}, across{-d.y, d.x, 0};
                const int lines = std::min(200, int(size / spacing));
                for (int k = 0; k < lines; ++k) {
                    const Vec3 start = c + across * (k * spacing - size / 2) - d * (size / 2);
                    mesh.append(
                        strokeMesh({start, start + d * size}, std::min(width, spacing * 0.6), false, z));
                }
                break;
            }
        }
        if (!mesh.vertices.empty()) s.addObject(name, s.addMesh(std::move(mesh)), flat(colour));
    }
    s.camera = [](double) { return CameraPose{{0, 0, kEye}, {0, 0, 0}, {0, 1, 0}, kFovDegrees * kPi / 180}; };
}

// ---- Type ---------------------------------------------------------------------------------------------

namespace {

const std::vector<FontFile>& fonts() {
    static const std::vector<FontFile> list = {
        {"/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf", "fonts-dejavu-core"},
        {"/usr/share/fonts/truetype/dejavu/DejaVuSans-Bold.ttf", "fonts-dejavu-core"},
        {"/usr/share/fonts/truetype/dejavu/DejaVuSerif.ttf", "fonts-dejavu-core"},
        {"/usr/share/fonts/truetype/dejavu/DejaVuSansMono.ttf", "fonts-dejavu-core"},
        {"/usr/share/fonts/truetype/dejavu/DejaVuSans-ExtraLight.ttf", "fonts-dejavu-extra"},
        {"/usr/share/fonts/truetype/dejavu/DejaVuSansCondensed-Oblique.ttf", "fonts-dejavu-extra"},
        {"/usr/share/fonts/truetype/dejavu/DejaVuSerif-Italic.ttf", "fonts-dejavu-extra"},
        {"/usr/share/fonts/truetype/liberation2/LiberationSans-Regular.ttf", "fonts-liberation2"},
        {"/usr/share/fonts/truetype/liberation2/LiberationSerif-Regular.ttf", "fonts-liberation2"},
        {"/usr/share/fonts/truetype/liberation2/LiberationMono-Bold.ttf", "fonts-liberation2"},
        {"/usr/share/fonts/truetype/freefont/FreeSans.ttf", "fonts-freefont-ttf"},
        {"/usr/share/fonts/truetype/freefont/FreeSerifItalic.ttf", "fonts-freefont-ttf"},
        {"/usr/share/fonts/truetype/freefont/FreeMono.ttf", "fonts-freefont-ttf"},
        {"/usr/share/fonts/opentype/urw-base35/NimbusRoman-Regular.otf", "fonts-urw-base35"},
        {"/usr/share/fonts/opentype/urw-base35/NimbusSans-Bold.otf", "fonts-urw-base35"},
        {"/usr/share/fonts/opentype/urw-base35/C059-Italic.otf", "fonts-urw-base35"},
        {"/usr/share/fonts/opentype/urw-base35/P052-Roman.otf", "fonts-urw-base35"},
        {"/usr/share/fonts/opentype/urw-base35/URWBookman-Light.otf", "fonts-urw-base35"},
        {"/usr/share/fonts/opentype/urw-base35/URWGothic-Book.otf", "fonts-urw-base35"},
        {"/usr/share/fonts/opentype/urw-base35/Z003-MediumItalic.otf", "fonts-urw-base35"},
    };
    return list;
}

// Words of several lengths and cases, digits and punctuation: what type on screens and pages shows.
const char* const kWords[] = {
    "the",     "quick",   "brown",     "fox",    "jumps",  "over",    "lazy",    "dog",      "Aliasing",
    "STAIRS",  "edge",    "pixel",     "sample", "filter", "1920",    "x1080",   "0.25",     "mm",
    "Menu",    "File",    "Edit",      "View",   "Help",   "OK",      "Cancel",  "Settings", "42%",
    "Zoom:",   "(a)",     "[b]",       "{c}",    "#7",     "@home",   "WWW",     "iiii",     "llll",
    "minimum", "Illegal", "shellfish", "Wavy",   "AVAVAV", "kerning", "Typeset", "qwerty",   "g-j-y",
    "&",       "/",       "\\",        "-->",    "=>",     "~",       "Ω",       "é",        "ß",
};

void blitLine(std::vector<uint8_t>& rgba, int size, FT_Face face, const std::string& text, int x0,
              int baseline, const Vec3& colour, int bandTop, int bandBottom) {
    // The line's colour over its band, alpha 0 (glyphs fill it in below).
    const uint8_t rgb[3] = {uint8_t(std::lround(colour.x * 255)), uint8_t(std::lround(colour.y * 255)),
                            uint8_t(std::lround(colour.z * 255))};
    for (int y = std::max(0, bandTop); y < std::min(size, bandBottom); ++y)
        for (int x = 0; x < size; ++x) {
            uint8_t* p = &rgba[(size_t(y) * size_t(size) + size_t(x)) * 4];
            if (p[3] == 0) p[0] = rgb[0], p[1] = rgb[1], p[2] = rgb[2];
        }
    int pen = x0;
    size_t i = 0;
    while (i < text.size() && pen < size) {
        // UTF-8 decoding of the few non-ASCII letters above.
        uint32_t code = uint8_t(text[i]);
        int extra = code >= 0xF0 ? 3 : code >= 0xE0 ? 2 : code >= 0xC0 ? 1 : 0;
        code &= extra == 3 ? 0x07u : extra == 2 ? 0x0Fu : extra == 1 ? 0x1Fu : 0x7Fu;
        ++i;
        for (; extra > 0 && i < text.size(); --extra, ++i) code = (code << 6) | (uint8_t(text[i]) & 0x3Fu);
        if (FT_Load_Char(face, code, FT_LOAD_RENDER)) continue;
        const FT_Bitmap& b = face->glyph->bitmap;
        const int left = pen + face->glyph->bitmap_left, top = baseline - face->glyph->bitmap_top;
        for (int r = 0; r < int(b.rows); ++r) {
            const int y = top + r;
            if (y < 0 || y >= size || y < bandTop || y >= bandBottom) continue;
            for (int c = 0; c < int(b.width); ++c) {
                const int x = left + c;
                if (x < 0 || x >= size) continue;
                uint8_t* p = &rgba[(size_t(y) * size_t(size) + size_t(x)) * 4];
                p[0] = rgb[0], p[1] = rgb[1], p[2] = rgb[2];
                p[3] = std::max(p[3], b.buffer[r * b.pitch + c]);
            }
        }
        pen += int(face->glyph->advance.x >> 6);
    }
}

}  // namespace

const std::vector<std::string>& typeFontFiles() {
    static const std::vector<std::string> list = [] {
        std::vector<std::string> paths;
        for (const FontFile& f : fonts()) paths.push_back(f.path);
        return paths;
    }();
    return list;
}

TextureImage makeTypeTexture(int size, uint64_t seed, double minEm, double maxEm) {
    if (size < 16 || minEm < 1 || maxEm < minEm) throw Error("makeTypeTexture: bad size or em range");
    Draw draw(seed ^ 0x7E47ull);
    FreeType freetype;
    TextureImage t;
    t.name = "type", t.width = size, t.height = size;
    t.rgba.assign(size_t(size) * size_t(size) * 4, 0);
    int y = int(draw.uniform(0, 0.3) * maxEm);
    while (true) {
        const double em = draw.logUniform(minEm, maxEm);
        const int band = int(std::ceil(em * 1.35)), baseline = y + int(std::ceil(em * 1.02));
        if (y + band > size) break;
        const FontFile& file = fonts()[size_t(draw.below(int(fonts().size())))];
        Face face(freetype.library, file);
        FT_Set_Pixel_Sizes(face.face, 0, FT_UInt(std::max(1.0, std::round(em))));
        std::string text;
        while (text.size() < size_t(3 * size / em))
            text += std::string(kWords[draw.below(int(std::size(kWords)))]) + (draw.chance(0.1) ? "  " : " ");
        blitLine(t.rgba, size, face.face, text, int(draw.uniform(-0.5, 0.2) * em * 4), baseline,
                 draw.colour(), y, y + band);
        y += band + int(draw.uniform(0, 0.6) * em);
    }
    return t;
}

void typeScene(Scene& s, const SceneOptions& o) {
    Draw draw(o.seed);
    s.background = draw.colour();
    s.addObject("page", s.addMesh(makeQuad(14, 8)), flat(s.background), [](double) {
        return Mat4::translation({0, 0, -0.01});
    });
    // A few panels behind the type, as in a user interface or a page layout.
    const int panels = draw.below(4);
    for (int i = 0; i < panels; ++i) {
        const double w = draw.uniform(0.5, 4), h = draw.uniform(0.3, 2.5);
        const Vec3 at = point(draw);
        s.addObject("panel", s.addMesh(makeQuad(w, h)), flat(draw.colour()), [at, i](double) {
            return Mat4::translation({at.x, at.y, -0.008 + 0.001 * i});
        });
    }
    // The type: a texture of 2048^2 texels over a square 1.17 view heights wide (about 7 texels a pixel
    // of a 256-row frame), ems from 4 to 48 pixels. Bilinear without mipmaps, cut out at coverage 0.5:
    // the glyphs' outlines, sampled once a pixel, alias like geometry.
    constexpr int kTexture = 2048;
    const double side = kViewHeight * 1.17, texelsPerPixel = kTexture / (side / kPixel);
    s.textures.push_back(makeTypeTexture(kTexture, o.seed, 4 * texelsPerPixel, 48 * texelsPerPixel));
    s.sampler = Sampler::Bilinear;
    Material type = flat({1, 1, 1});
    type.pattern = Pattern::Texture, type.texture = 0, type.alphaCutout = true;
    const double turn = draw.chance(0.5) ? 0 : draw.uniform(-0.5, 0.5);
    s.addObject("type", s.addMesh(makeQuad(side, side)), type, [turn](double) {
        return Mat4::rotation({0, 0, 1}, turn);
    });
    s.camera = [](double) { return CameraPose{{0, 0, kEye}, {0, 0, 0}, {0, 1, 0}, kFovDegrees * kPi / 180}; };
}

}  // namespace dejag::render
