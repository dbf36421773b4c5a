#include "base/progress.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>

namespace dejag {

namespace {
// The bar drawn last on the terminal (one at a time; bars nest only in sequence). Guarded: log lines
// may come from worker threads.
std::mutex activeMutex;
Progress* active = nullptr;
}  // namespace

void printLine(std::FILE* stream, const std::string& line) {
    std::lock_guard<std::mutex> lock(activeMutex);
    Progress* bar = active;
    if (bar && bar->drawn_) {
        std::fputs("\r\033[K", stderr);
        std::fflush(stderr);
    }
    std::fprintf(stream, "%s\n", line.c_str());
    std::fflush(stream);
    if (bar && bar->drawn_) bar->draw(false);
}

std::string formatDuration(double seconds) {
    if (!std::isfinite(seconds) || seconds < 0) return "?";
    const long s = long(seconds + 0.5), h = s / 3600, m = (s / 60) % 60, r = s % 60;
    char text[32];
    if (h > 0)
        std::snprintf(text, sizeof text, "%ld:%02ld:%02ld", h, m, r);
    else
        std::snprintf(text, sizeof text, "%ld:%02ld", m, r);
    return text;
}

Progress::Progress(std::string label, int64_t total, bool quiet)
    : label_(std::move(label)),
      total_(total),
      quiet_(quiet),
      terminal_(isatty(STDERR_FILENO) != 0),
      start_(std::chrono::steady_clock::now()),
      lastDraw_(start_) {}

Progress::~Progress() {
    std::lock_guard<std::mutex> lock(activeMutex);
    if (active == this) active = nullptr;
    if (!finished_ && drawn_) std::fputc('\n', stderr);
}

void Progress::resumeAt(int64_t done) {
    done_ = resumed_ = done;
}

void Progress::advance(int64_t count, const std::string& detail) {
    done_ += count;
    detail_ = detail;
    const auto now = std::chrono::steady_clock::now();
    const double sinceDraw = std::chrono::duration<double>(now - lastDraw_).count();
    if (done_ >= total_) return finish();
    if (sinceDraw >= (terminal_ ? 0.1 : 10.0)) {
        std::lock_guard<std::mutex> lock(activeMutex);
        draw(false);
    }
}

void Progress::finish() {
    if (finished_) return;
    finished_ = true;
    std::lock_guard<std::mutex> lock(activeMutex);
    draw(true);
    if (active == this) active = nullptr;
}

void Progress::draw(bool final) {
    lastDraw_ = std::chrono::steady_clock::now();
    if (quiet_) return;
    const double elapsed = std::chrono::duration<double>(lastDraw_ - start_).count();
    const double rate = elapsed > 0 ? double(done_ - resumed_) / elapsed : 0.0;
    const double eta = rate > 0 ? double(std::max<int64_t>(total_ - done_, 0)) / rate : NAN;
    const int width = 24;
    const int filled = total_ > 0 ? int(double(width) * double(done_) / double(total_)) : width;
    std::string bar(size_t(filled), '#');
    bar.resize(size_t(width), '.');
    char line[512];
    std::snprintf(line, sizeof line, "%s [%s] %lld/%lld  %.2f/s  %s %s%s%s", label_.c_str(), bar.c_str(),
                  static_cast<long long>(done_), static_cast<long long>(total_), rate, final ? "took" : "ETA",
                  formatDuration(final ? elapsed : eta).c_str(), detail_.empty() ? "" : "  ",
                  detail_.c_str());
    if (terminal_) {
        std::fprintf(stderr, "\r\033[K%s%s", line, final ? "\n" : "");
        drawn_ = !final;
        active = this;
    } else
        std::fprintf(stderr, "%s\n", line);
    std::fflush(stderr);
}

}  // namespace dejag
