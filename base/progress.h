// dejag/base: a progress bar with rate and ETA on stderr for long work. On a terminal it redraws one
// line; otherwise (logs, CI) it prints a line at most every 10 s and at the end. Quiet mode prints nothing.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <string>

namespace dejag {

class Progress {
  public:
    Progress(std::string label, int64_t total, bool quiet = false);
    ~Progress();
    // Work done before this run (a resumed job): counted in the bar, not in the rate or the ETA.
    void resumeAt(int64_t done);
    // A total learnt on the way (a video's frame count is the container's estimate).
    void setTotal(int64_t total) { total_ = total; }
    // Marks `count` more items done; `detail` (optional) is shown after the counts.
    void advance(int64_t count = 1, const std::string& detail = "");
    void finish();

  private:
    void draw(bool final);
    std::string label_;
    int64_t total_, done_ = 0, resumed_ = 0;
    bool drawn_ = false;  // the bar's line is on the terminal, unfinished
    friend void printLine(std::FILE* stream, const std::string& line);
    bool quiet_, terminal_, finished_ = false;
    std::string detail_;
    std::chrono::steady_clock::time_point start_, lastDraw_;
};

// Prints `line` and a newline to `stream` (stdout or stderr), flushed. While a progress bar is drawn on
// the terminal, the line goes above it: the bar is cleared first and drawn again after, so log lines and
// the bar never share a line.
void printLine(std::FILE* stream, const std::string& line);

// "1:02:03" / "2:03" for a duration in seconds.
std::string formatDuration(double seconds);

}  // namespace dejag
