// dejag/base: the one exception type every stage throws for bad input or failed I/O.
//
// The message is a complete sentence fragment that names the file or value at fault, so the CLI can
// print it as the single error line the user sees ("dejag metrics: 'b.png' is 640x480, 'a.png' is ...").
#pragma once

#include <stdexcept>
#include <string>

namespace dejag {

class Error : public std::runtime_error {
  public:
    explicit Error(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace dejag
