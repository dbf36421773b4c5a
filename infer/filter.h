// dejag/infer: one face for every anti-aliasing method, after Open Image Denoise's filter object.
//
// A method is made by name from a parameter map (makeFilter): the factory reads the parameters the method
// declares (MethodSpec: name, default, help) and refuses any that no method of the chain read, so a
// misspelt or misplaced setting is an error instead of being ignored (as pbrt-v4 reports unused
// parameters). A method declares the buffers of a frame it needs and those it uses when present; it may
// keep state across frames (TAA's history: reset() starts over at a cut); it runs on a frame and reports
// its figures (milliseconds, the fraction of the frame it processed). A chain ("fxaa,cnn") is a filter of
// filters, each stage reading the one before.
//
// Adding a method: a file pair holding the algorithm and its MethodSpec (name, parameters, buffers, a
// make function), one line in the table of infer/filter.cpp, and its tests.
#pragma once

#include <functional>
#include <initializer_list>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "infer/frame.h"

namespace dejag::infer {

// The settings of the methods of a chain: name -> text, each recording where it came from (a flag such
// as "--preset", or "--set NAME=VALUE") for the error messages. The methods read them through
// MethodParameters, which knows their declared defaults and ranges.
class FilterParameters {
  public:
    FilterParameters() = default;
    // {{"preset", "12"}, {"gate", "off"}}: settings given in code (origin "NAME=VALUE").
    FilterParameters(std::initializer_list<std::pair<std::string, std::string>> settings);
    // Throws dejag::Error if name was given twice.
    void set(const std::string& name, const std::string& value, const std::string& origin = "");
    // "NAME=VALUE" (as --set takes it).
    void setAssignment(const std::string& assignment);
    bool has(const std::string& name) const { return entries_.count(name) > 0; }
    // Paths (a model file) pass through this before a method opens them: the app resolves the shipped
    // models/... paths from any working directory.
    void setPathResolver(std::function<std::string(const std::string&)> resolve) {
        resolve_ = std::move(resolve);
    }
    // Throws dejag::Error naming the first parameter that no method read, and what `methods` take.
    void requireAllUsed(const std::string& methods, const std::string& accepted) const;

  private:
    friend class MethodParameters;
    struct Entry {
        std::string value, origin;
        mutable bool used = false;
    };
    std::map<std::string, Entry> entries_;
    std::function<std::string(const std::string&)> resolve_;
};

// One parameter a method reads: its name, its default as text (as --list-methods prints it) and help.
struct ParameterSpec {
    std::string name, defaultValue, help;
};

class Filter;

// A method of the table: what --list-methods prints and what makeFilter builds.
struct MethodSpec {
    std::string name, summary;
    std::vector<ParameterSpec> parameters;
    BufferSet needs = 0;     // buffers it cannot run without
    BufferSet optional = 0;  // buffers it uses when the frame has them
    bool temporal = false;   // keeps state across frames (reset() at a cut)
    std::function<std::unique_ptr<Filter>(class MethodParameters&)> make;
};

// The parameters as one method sees them: typed reads with the declared default and a range check.
// Reading a parameter the method did not declare is a programming error (std::logic_error).
class MethodParameters {
  public:
    MethodParameters(const MethodSpec& spec, const FilterParameters& given) : spec_(spec), given_(given) {}
    std::string text(const std::string& name) const;
    std::string path(const std::string& name) const;  // through the path resolver
    int integer(const std::string& name, int lowest, int highest) const;
    double number(const std::string& name, double lowest, double highest) const;
    bool flag(const std::string& name) const;  // true/false, on/off, yes/no, 1/0
    // "NAME" or "--flag" for messages.
    std::string origin(const std::string& name) const;
    const std::string& method() const { return spec_.name; }

  private:
    const ParameterSpec& declared(const std::string& name) const;
    const MethodSpec& spec_;
    const FilterParameters& given_;
};

// What a filter did on its last frame.
struct FilterFigures {
    double ms = 0;                 // wall time of the last apply()
    double processedFraction = 1;  // the share of the frame it worked on (gated methods skip parts)
    std::vector<std::pair<std::string, double>> extra;          // e.g. tiles, tiles_processed
    std::vector<std::pair<std::string, std::string>> settings;  // e.g. model, precision
};

class Filter {
  public:
    virtual ~Filter() = default;
    // The name it was made by ("fxaa"; "fxaa,cnn" for a chain).
    const std::string& name() const { return name_; }
    virtual BufferSet needs() const = 0;
    virtual BufferSet uses() const { return needs(); }  // needs plus the optional buffers
    virtual bool temporal() const { return false; }
    // Filters frame.colour into out (same layout: width x height x frame.channels, R G B first,
    // sRGB-encoded; the channels after R G B pass through). Throws dejag::Error if the frame lacks a
    // buffer it needs, naming it. Allocates only when the frame's size grows.
    void apply(const Frame& frame, float* out);
    // Starts a new history (a cut); no-op for a method without state.
    virtual void reset() {}
    const FilterFigures& figures() const { return figures_; }
    // The stages of a chain (empty for a single method).
    virtual std::vector<const Filter*> stages() const { return {}; }

  protected:
    explicit Filter(std::string name) : name_(std::move(name)) {}
    virtual void process(const Frame& frame, float* out) = 0;
    FilterFigures figures_;

  private:
    std::string name_;
};

// "none": the frame unchanged (the baseline every comparison starts from).
MethodSpec noneMethod();

// Every method, in the order --list-methods prints them.
const std::vector<MethodSpec>& filterMethods();
const MethodSpec* findMethod(const std::string& name);

// One method ("fxaa") or a chain ("fxaa,cnn", "taa,cnn"). Throws dejag::Error for an unknown method (naming
// the known ones), an empty chain element, a parameter out of range, or a parameter that no method of the
// chain reads.
std::unique_ptr<Filter> makeFilter(const std::string& methods, const FilterParameters& parameters);

// The table as text: each method, its summary, the buffers it needs and uses, and its parameters with
// their defaults.
std::string describeMethods();

}  // namespace dejag::infer
