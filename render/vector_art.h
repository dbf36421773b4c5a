// dejag/render: flat 2D content drawn as geometry facing the camera (docs/scenes.md, "Vector art and
// type"): strokes and fans at every angle and width, polygons, curves, rings, hatching and map-like roads;
// and lines of type set from the fonts of Debian's font packages. What a frame without depth holds —
// a screenshot, a diagram, a page — rendered by dejag itself, with the same jittered truth as every scene.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "render/scene.h"

namespace dejag::render {

// The fonts the type scene draws from, in a stable order (the files of fonts-dejavu-core,
// fonts-dejavu-extra, fonts-liberation2, fonts-freefont-ttf and fonts-urw-base35).
const std::vector<std::string>& typeFontFiles();

// A `size` x `size` RGBA texture of lines of text, each in one of typeFontFiles() at its own size and
// colour: alpha is the glyphs' coverage (FreeType's anti-aliased rasterisation), RGB the line's colour
// over the line's whole band, so filtering at a glyph's border never mixes in another colour. Sizes
// are em heights in texels, log-uniform in [minEm, maxEm]. Throws dejag::Error naming a missing font
// file and the package that installs it.
TextureImage makeTypeTexture(int size, uint64_t seed, double minEm, double maxEm);

// Scene builders (registered in sceneCatalogue()).
void vectorArtScene(Scene& scene, const SceneOptions& options);
void typeScene(Scene& scene, const SceneOptions& options);

}  // namespace dejag::render
