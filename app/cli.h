// dejag/app: helpers shared by the subcommands of the `dejag` binary.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace dejag::cli {

// Adds --threads N (default: DEJAG_THREADS or the core count) and --simd LEVEL to a subcommand; call
// applyRuntimeOptions() at the start of its callback.
struct RuntimeOptions {
    int threads = 0;
    std::string simd;
};
void addRuntimeOptions(CLI::App* command, RuntimeOptions& options);
void applyRuntimeOptions(const RuntimeOptions& options);

// Every float option of `app` and its subcommands refuses NaN and infinities, every unsigned one a
// negative number (which would wrap); called once, after all subcommands are registered.
void guardNumericOptions(CLI::App& app);
// One voice for every --help: the help flag's text in lower case like every option's, and an example
// command at the end of each (sub)command's help (the table in cli.cpp; a command without one throws).
void finishHelp(CLI::App& app);

struct Size {
    int width = 0, height = 0;
};
// "1920x1080" -> {1920, 1080}; throws dejag::Error naming `what` on anything else or a side outside 1..16384.
Size parseSize(const std::string& text, const std::string& what);

// "a,b,,c" -> {"a", "b", "c"}: the comma-separated lists of the flags (empty items dropped).
std::vector<std::string> splitList(const std::string& text);

// A model file as given, or — when the path is relative, starts with models/ and is not in the working
// directory — the shipped copy found from the binary: the source tree's models/ for a build tree
// (build/PRESET/dejag) or share/dejag/models for an installed bin/dejag. So `dejag filter --method cnn`
// finds the shipped network from any directory. Unchanged when there is none (the reader then names it).
std::string shippedModelPath(const std::string& path);

// "-" for one image on standard input or output. input("-") reads standard input to the end into a
// private temporary folder and returns that file's path, its format told by its first bytes (PNG, JPEG,
// TIFF or OpenEXR; anything else is one error line). output("-", EXT) returns a path there with that
// extension; finish() copies what was written to it to standard output. Any other path passes unchanged.
// The folder goes with the object.
class StandardStreams {
  public:
    StandardStreams() = default;
    ~StandardStreams();
    StandardStreams(const StandardStreams&) = delete;
    StandardStreams& operator=(const StandardStreams&) = delete;
    std::string input(const std::string& path);
    std::string output(const std::string& path, const std::string& extension);
    bool writesStandardOutput() const { return !output_.empty(); }
    void finish();

  private:
    const std::string& folder();
    std::string folder_, output_;
};
std::vector<std::string> shippedModelPaths(const std::vector<std::string>& paths);

// The command line as typed (set by main), recorded in what a command writes (run.json, model cards).
std::string& invocation();

}  // namespace dejag::cli
