// dejag/base: a progress bar with rate and ETA on stderr for long work. On a terminal it redraws one
// line; otherwise (logs, CI) it prints a line at most every 10 s and at the end. Quiet mode prints nothing.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

namespace dejag {

class Progress {
  public:
    Progress(std::string label, int64_t total, bool quiet = false);
    ~Progress();
    // Marks `count` more items done; `detail` (optional) is shown after the counts.
    void advance(int64_t count = 1, const std::string& detail = "");
    void finish();

  private:
    void draw(bool final);
    std::string label_;
    int64_t total_, done_ = 0;
    bool quiet_, terminal_, finished_ = false;
    std::string detail_;
    std::chrono::steady_clock::time_point start_, lastDraw_;
};

// "1:02:03" / "2:03" for a duration in seconds.
std::string formatDuration(double seconds);

}  // namespace dejag
