#include "data/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "base/error.h"
#include "data/image.h"

namespace dejag {

namespace {

// A "nice" tick step (1, 2 or 5 times a power of ten) giving about `count` ticks over `span`.
double tickStep(double span, int count) {
    const double raw = span / std::max(count, 1);
    const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (raw <= m * magnitude) return m * magnitude;
    return 10 * magnitude;
}

std::string formatTick(double value, double step) {
    char text[32];
    if (std::abs(value) >= 1e5 || (std::abs(value) > 0 && std::abs(value) < 1e-3))
        std::snprintf(text, sizeof text, "%.0e", value);
    else
        std::snprintf(text, sizeof text, "%.*f", std::max(0, int(-std::floor(std::log10(step) + 1e-9))),
                      value);
    return text;
}

cv::Scalar bgr(Rgb c) {
    return cv::Scalar(c.b * 255, c.g * 255, c.r * 255);
}

struct Range {
    double low = std::numeric_limits<double>::infinity(), high = -std::numeric_limits<double>::infinity();
    void add(double v) {
        if (std::isfinite(v)) low = std::min(low, v), high = std::max(high, v);
    }
    void pad() {
        if (!(low <= high)) low = 0, high = 1;
        if (high - low < 1e-12) low -= 0.5, high += 0.5;
        const double margin = 0.05 * (high - low);
        low -= margin, high += margin;
    }
};

// An 8-bit BGR OpenCV canvas written as an 8-bit RGB PNG (atomically, by writeImage).
void writeCanvas(const std::string& path, const cv::Mat& canvas) {
    Image image(canvas.cols, canvas.rows, {"R", "G", "B"}, PixelType::UInt8);
    for (int y = 0; y < canvas.rows; ++y)
        for (int x = 0; x < canvas.cols; ++x) {
            const cv::Vec3b c = canvas.at<cv::Vec3b>(y, x);
            float* p = &image.pixels[(size_t(y) * size_t(canvas.cols) + size_t(x)) * 3];
            p[0] = c[2] / 255.0f, p[1] = c[1] / 255.0f, p[2] = c[0] / 255.0f;
        }
    writeImage(path, image);
}

}  // namespace

std::vector<PlotBox> placePointLabels(const std::vector<PlotBox>& markers,
                                      const std::vector<std::pair<int, int>>& anchors,
                                      const std::vector<std::pair<int, int>>& sizes, int width, int height) {
    auto overlap = [](const PlotBox& a, const PlotBox& b) {
        return a.x < b.x + b.width && b.x < a.x + a.width && a.y < b.y + b.height && b.y < a.y + a.height;
    };
    std::vector<PlotBox> taken = markers, placed;
    for (size_t i = 0; i < anchors.size() && i < sizes.size(); ++i) {
        const auto [x, y] = anchors[i];
        const auto [w, h] = sizes[i];
        // Top-left corners: right and up first (the text's baseline 5 px above the marker's centre),
        // right and down, left of it, centred above and below, then one line further out.
        const std::pair<int, int> corners[] = {
            {x + 7, y - 5 - h},         {x + 7, y + 4},        {x - 7 - w, y - 5 - h}, {x - 7 - w, y + 4},
            {x - w / 2, y - 9 - h},     {x - w / 2, y + 9},    {x + 7, y - 5 - 2 * h}, {x + 7, y + 4 + h},
            {x - 7 - w, y - 5 - 2 * h}, {x - 7 - w, y + 4 + h}};
        std::optional<PlotBox> chosen, onCanvas;
        for (const auto& [cx, cy] : corners) {
            const PlotBox box{cx, cy, w, h};
            if (box.x < 2 || box.y < 2 || box.x + w > width - 2 || box.y + h > height - 2) continue;
            if (!onCanvas) onCanvas = box;
            if (std::none_of(taken.begin(), taken.end(), [&](const PlotBox& t) { return overlap(t, box); })) {
                chosen = box;
                break;
            }
        }
        const PlotBox box = chosen ? *chosen : onCanvas ? *onCanvas : PlotBox{x + 7, y - 5 - h, w, h};
        taken.push_back(box);
        placed.push_back(box);
    }
    return placed;
}

Rgb plotColour(int index) {
    // Tableau 10: distinct for the common kinds of colour blindness.
    static const Rgb palette[] = {{0.12f, 0.47f, 0.71f}, {1.00f, 0.50f, 0.05f}, {0.17f, 0.63f, 0.17f},
                                  {0.84f, 0.15f, 0.16f}, {0.58f, 0.40f, 0.74f}, {0.55f, 0.34f, 0.29f},
                                  {0.89f, 0.47f, 0.76f}, {0.50f, 0.50f, 0.50f}, {0.74f, 0.74f, 0.13f},
                                  {0.09f, 0.75f, 0.81f}};
    return palette[size_t(index) % std::size(palette)];
}

int plotMarkerShape(int index) {
    return (index / 10) % 3;
}

namespace {
void drawMarker(cv::Mat& canvas, cv::Point p, int shape, const cv::Scalar& colour) {
    if (shape == 1) {
        cv::rectangle(canvas, {p.x - 4, p.y - 4}, {p.x + 4, p.y + 4}, colour, cv::FILLED, cv::LINE_AA);
    } else if (shape == 2) {
        const std::vector<cv::Point> triangle = {{p.x, p.y - 6}, {p.x - 6, p.y + 4}, {p.x + 6, p.y + 4}};
        cv::fillConvexPoly(canvas, triangle, colour, cv::LINE_AA);
    } else {
        cv::circle(canvas, p, 5, colour, cv::FILLED, cv::LINE_AA);
    }
}
}  // namespace

void writePlotPng(const std::string& path, const Plot& plot) {
    const int W = std::max(plot.width, 200), H = std::max(plot.height, 150);
    cv::Mat canvas(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
    const int font = cv::FONT_HERSHEY_SIMPLEX;
    int legendWidth = 0;
    if (plot.legendOutside)
        for (const PlotSeries& series : plot.series) {
            int base = 0;
            legendWidth =
                std::max(legendWidth, cv::getTextSize(series.name, font, 0.42, 1, &base).width + 44);
        }
    const int left = 80, right = 20 + legendWidth, top = 40, bottom = 60;
    const cv::Rect area(left, top, W - left - right, H - top - bottom);
    auto mapX = [&](double x) { return plot.logX ? std::log10(std::max(x, 1e-300)) : x; };
    Range xr, yr;
    for (const PlotSeries& s : plot.series)
        for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i)
            if (std::isfinite(s.x[i]) && std::isfinite(s.y[i]) && (!plot.logX || s.x[i] > 0))
                xr.add(mapX(s.x[i])), yr.add(s.y[i]);
    xr.pad(), yr.pad();
    auto px = [&](double x) {
        return cv::Point2d(area.x + (mapX(x) - xr.low) / (xr.high - xr.low) * area.width, 0).x;
    };
    auto py = [&](double y) {
        return area.y + area.height - (y - yr.low) / (yr.high - yr.low) * area.height;
    };
    const cv::Scalar ink(40, 40, 40), grid(225, 225, 225);
    // Grid, ticks and tick labels.
    const double ys = tickStep(yr.high - yr.low, 6);
    for (double y = std::ceil(yr.low / ys) * ys; y <= yr.high; y += ys) {
        const int v = int(std::lround(py(y)));
        cv::line(canvas, {area.x, v}, {area.x + area.width, v}, grid, 1);
        const std::string t = formatTick(y, ys);
        int base = 0;
        const cv::Size size = cv::getTextSize(t, font, 0.4, 1, &base);
        cv::putText(canvas, t, {area.x - 6 - size.width, v + size.height / 2}, font, 0.4, ink, 1,
                    cv::LINE_AA);
    }
    const double xs = plot.logX ? 1.0 : tickStep(xr.high - xr.low, 8);
    for (double x = std::ceil(xr.low / xs) * xs; x <= xr.high; x += xs) {
        const double value = plot.logX ? std::pow(10.0, x) : x;
        const int u = int(std::lround(area.x + (x - xr.low) / (xr.high - xr.low) * area.width));
        cv::line(canvas, {u, area.y}, {u, area.y + area.height}, grid, 1);
        const std::string t = formatTick(value, plot.logX ? std::max(value, 1e-300) : xs);
        int base = 0;
        const cv::Size size = cv::getTextSize(t, font, 0.4, 1, &base);
        cv::putText(canvas, t, {u - size.width / 2, area.y + area.height + 16}, font, 0.4, ink, 1,
                    cv::LINE_AA);
    }
    cv::rectangle(canvas, area, ink, 1);
    // Series: lines and markers first, point labels after (placed so that none overlaps another or a
    // marker, nor leaves the canvas: two methods of nearly equal cost and error used to print on top of
    // each other, and a label near the right edge was cut off).
    struct PointLabel {
        cv::Point at;
        const std::string* text;
    };
    std::vector<PointLabel> pointLabels;
    std::vector<PlotBox> markerBoxes;
    for (size_t k = 0; k < plot.series.size(); ++k) {
        const PlotSeries& s = plot.series[k];
        const cv::Scalar colour = bgr(plotColour(int(k)));
        std::vector<cv::Point> run;
        auto flush = [&] {
            if (s.lines && run.size() >= 2) cv::polylines(canvas, run, false, colour, 2, cv::LINE_AA);
            run.clear();
        };
        for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
            if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i]) || (plot.logX && s.x[i] <= 0)) {
                flush();
                continue;
            }
            const cv::Point p(int(std::lround(px(s.x[i]))), int(std::lround(py(s.y[i]))));
            run.push_back(p);
            if (s.markers) {
                drawMarker(canvas, p, plotMarkerShape(int(k)), colour);
                markerBoxes.push_back({p.x - 6, p.y - 6, 13, 13});
            }
            if (s.labels && i < s.pointLabels.size()) pointLabels.push_back({p, &s.pointLabels[i]});
        }
        flush();
    }
    std::vector<std::pair<int, int>> anchors, sizes;
    std::vector<int> ascents;
    for (const PointLabel& label : pointLabels) {
        int base = 0;
        const cv::Size size = cv::getTextSize(*label.text, font, 0.38, 1, &base);
        anchors.emplace_back(label.at.x, label.at.y);
        sizes.emplace_back(size.width, size.height + base);
        ascents.push_back(size.height);
    }
    // Labels stay left of an outside legend; with one, a label that found no free spot is left out (the
    // legend names its marker) rather than printed over another.
    const std::vector<PlotBox> boxes = placePointLabels(markerBoxes, anchors, sizes, W - legendWidth, H);
    std::vector<PlotBox> drawn;
    const auto overlaps = [](const PlotBox& a, const PlotBox& b) {
        return a.x < b.x + b.width && b.x < a.x + a.width && a.y < b.y + b.height && b.y < a.y + a.height;
    };
    for (size_t i = 0; i < pointLabels.size(); ++i) {
        if (plot.legendOutside &&
            std::any_of(drawn.begin(), drawn.end(), [&](const PlotBox& b) { return overlaps(b, boxes[i]); }))
            continue;
        drawn.push_back(boxes[i]);
        cv::putText(canvas, *pointLabels[i].text, {boxes[i].x, boxes[i].y + ascents[i]}, font, 0.38, ink, 1,
                    cv::LINE_AA);
    }
    // Legend (top right inside the plot area), title and axis labels.
    int legendY = area.y + 18;
    for (size_t k = 0; k < plot.series.size(); ++k) {
        if (plot.series[k].name.empty()) continue;
        int base = 0;
        const cv::Size size = cv::getTextSize(plot.series[k].name, font, 0.42, 1, &base);
        const int x = plot.legendOutside ? area.x + area.width + 16 : area.x + area.width - size.width - 36;
        cv::rectangle(canvas, {x - 4, legendY - size.height - 3}, {x + size.width + 30, legendY + 5},
                      cv::Scalar(255, 255, 255), cv::FILLED);
        if (plot.series[k].lines)
            cv::line(canvas, {x, legendY - 4}, {x + 20, legendY - 4}, bgr(plotColour(int(k))), 3,
                     cv::LINE_AA);
        if (plot.series[k].markers)
            drawMarker(canvas, {x + 10, legendY - 4}, plotMarkerShape(int(k)), bgr(plotColour(int(k))));
        cv::putText(canvas, plot.series[k].name, {x + 26, legendY}, font, 0.42, ink, 1, cv::LINE_AA);
        legendY += size.height + 10;
    }
    cv::putText(canvas, plot.title, {left, 26}, font, 0.6, ink, 1, cv::LINE_AA);
    {
        int base = 0;
        const cv::Size size = cv::getTextSize(plot.xLabel, font, 0.45, 1, &base);
        cv::putText(canvas, plot.xLabel, {area.x + area.width / 2 - size.width / 2, H - 14}, font, 0.45, ink,
                    1, cv::LINE_AA);
    }
    {
        // The y label, rotated: drawn on its own strip, then turned.
        int base = 0;
        const cv::Size size = cv::getTextSize(plot.yLabel, font, 0.45, 1, &base);
        cv::Mat strip(size.height + 8, size.width + 4, CV_8UC3, cv::Scalar(255, 255, 255));
        cv::putText(strip, plot.yLabel, {2, size.height + 2}, font, 0.45, ink, 1, cv::LINE_AA);
        cv::Mat turned;
        cv::rotate(strip, turned, cv::ROTATE_90_COUNTERCLOCKWISE);
        const int y0 = std::max(0, area.y + area.height / 2 - turned.rows / 2);
        if (y0 + turned.rows <= H && turned.cols + 6 <= left)
            turned.copyTo(canvas(cv::Rect(6, y0, turned.cols, turned.rows)));
    }
    writeCanvas(path, canvas);
}

void writeMosaicPng(const std::string& path, const std::vector<std::vector<Image>>& rows,
                    const std::vector<std::string>& rowLabels, const std::vector<std::string>& columnLabels) {
    if (rows.empty() || rows[0].empty()) throw Error("a mosaic needs at least one image");
    const int cw = rows[0][0].width, ch = rows[0][0].height, columns = int(rows[0].size());
    const int font = cv::FONT_HERSHEY_SIMPLEX;
    const cv::Scalar ink(40, 40, 40);
    // Column labels wider than their column wrap at spaces (a word too long for a line is cut).
    auto textWidth = [&](const std::string& text) {
        int baseline = 0;
        return cv::getTextSize(text, font, 0.45, 1, &baseline).width;
    };
    std::vector<std::vector<std::string>> columnLines;
    size_t mostLines = 1;
    for (const std::string& label : columnLabels) {
        std::vector<std::string> lines{""};
        size_t start = 0;
        while (start < label.size()) {
            size_t end = label.find(' ', start);
            if (end == std::string::npos) end = label.size();
            std::string word = label.substr(start, end - start);
            while (word.size() > 1 && textWidth(word) > cw - 6) word.pop_back();
            const std::string joined = lines.back().empty() ? word : lines.back() + " " + word;
            if (textWidth(joined) <= cw - 6)
                lines.back() = joined;
            else
                lines.push_back(word);
            start = end + 1;
        }
        mostLines = std::max(mostLines, lines.size());
        columnLines.push_back(std::move(lines));
    }
    int left = 150;
    for (const std::string& label : rowLabels) left = std::max(left, textWidth(label) + 14);
    const int lineHeight = 15, top = 12 + int(mostLines) * lineHeight, gap = 4;
    const int W = left + columns * (cw + gap), H = top + int(rows.size()) * (ch + gap);
    cv::Mat canvas(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
    for (size_t r = 0; r < rows.size(); ++r) {
        if (int(rows[r].size()) != columns) throw Error("mosaic rows differ in length");
        for (int c = 0; c < columns; ++c) {
            const Image& im = rows[r][size_t(c)];
            if (im.width != cw || im.height != ch || im.channels() < 3)
                throw Error("mosaic cells must be RGB images of one size");
            const int x0 = left + c * (cw + gap), y0 = top + int(r) * (ch + gap);
            for (int y = 0; y < ch; ++y)
                for (int x = 0; x < cw; ++x) {
                    const float* p = &im.pixels[(size_t(y) * size_t(cw) + size_t(x)) * size_t(im.channels())];
                    auto byte = [](float v) {
                        return uchar(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
                    };
                    canvas.at<cv::Vec3b>(y0 + y, x0 + x) = cv::Vec3b(byte(p[2]), byte(p[1]), byte(p[0]));
                }
        }
        if (r < rowLabels.size())
            cv::putText(canvas, rowLabels[r], {6, top + int(r) * (ch + gap) + ch / 2}, font, 0.45, ink, 1,
                        cv::LINE_AA);
    }
    for (int c = 0; c < columns && c < int(columnLines.size()); ++c)
        for (size_t line = 0; line < columnLines[size_t(c)].size(); ++line)
            cv::putText(canvas, columnLines[size_t(c)][line],
                        {left + c * (cw + gap) + 4, 20 + int(line) * lineHeight}, font, 0.45, ink, 1,
                        cv::LINE_AA);
    writeCanvas(path, canvas);
}

}  // namespace dejag
