// dejag/data: PNG charts for logs and reports (training curves, run time against error).
//
// A chart is a few named series of (x, y) points drawn as lines, markers or both, with axes, ticks at
// round values, a legend and a title. Non-finite points are skipped. Written atomically.
#pragma once

#include <string>
#include <vector>

#include "data/colormap.h"
#include "data/image.h"

namespace dejag {

struct PlotSeries {
    std::string name;
    std::vector<double> x, y;
    bool lines = true, markers = false;
    bool labels = false;  // write `pointLabels[i]` next to each marker
    std::vector<std::string> pointLabels;
};

struct Plot {
    std::string title, xLabel, yLabel;
    std::vector<PlotSeries> series;
    bool logX = false;
    int width = 900, height = 540;
    bool legendOutside = false;  // the legend right of the plot area (many series), not over its top right
};

// Throws dejag::Error if the file cannot be written.
void writePlotPng(const std::string& path, const Plot& plot);

// Where writePlotPng puts the point labels: label i (width, height in pixels) next to the marker at
// anchor i, in order, each at the first free spot around its marker (right and up, right and down,
// left, above, below, then further out) that overlaps no marker (blocked: a box per marker) and no label
// placed before it and lies inside the width x height canvas; on the canvas, overlapping, if none is free.
struct PlotBox {
    int x = 0, y = 0, width = 0, height = 0;
};
std::vector<PlotBox> placePointLabels(const std::vector<PlotBox>& markers,
                                      const std::vector<std::pair<int, int>>& anchors,
                                      const std::vector<std::pair<int, int>>& sizes, int width, int height);

// A grid of RGB images (sRGB-encoded, [0, 1]; every cell the same size) with a label above each column
// and one left of each row: side-by-side comparisons. Throws dejag::Error on mismatched cells.
void writeMosaicPng(const std::string& path, const std::vector<std::vector<Image>>& rows,
                    const std::vector<std::string>& rowLabels, const std::vector<std::string>& columnLabels);

// The colour of series `index` (a fixed qualitative palette of 10, repeated).
Rgb plotColour(int index);
// The marker of series `index`: 0 circle, 1 square, 2 triangle (the next shape each time the palette
// repeats, so 30 series stay apart).
int plotMarkerShape(int index);

}  // namespace dejag
