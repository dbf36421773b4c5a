// dejag/data: PNG charts for logs and reports (training curves, run time against error).
//
// A chart is a few named series of (x, y) points drawn as lines, markers or both, with axes, ticks at
// round values, a legend and a title. Non-finite points are skipped. Written atomically.
#pragma once

#include <string>
#include <vector>

#include "data/colormap.h"

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
};

// Throws dejag::Error if the file cannot be written.
void writePlotPng(const std::string& path, const Plot& plot);

// The colour of series `index` (a fixed qualitative palette).
Rgb plotColour(int index);

}  // namespace dejag
