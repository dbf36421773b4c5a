#include "infer/filter.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <set>
#include <sstream>
#include <stdexcept>

#include "base/error.h"
#include "base/thread_pool.h"
#include "base/timer.h"
#include "infer/cnn.h"
#include "infer/cnn_temporal.h"
#include "infer/fxaa.h"
#include "infer/smaa.h"
#include "infer/taa.h"
#include "infer/taa_hq.h"

namespace dejag::infer {

// ---- parameters ----

void FilterParameters::set(const std::string& name, const std::string& value, const std::string& origin) {
    if (name.empty()) throw Error("a method parameter needs a name (--set NAME=VALUE)");
    const std::string from = origin.empty() ? "--set " + name + "=" + value : origin;
    if (auto it = entries_.find(name); it != entries_.end())
        throw Error(from + ": parameter '" + name + "' is already set (by " + it->second.origin + ")");
    entries_[name] = Entry{value, from};
}

FilterParameters::FilterParameters(std::initializer_list<std::pair<std::string, std::string>> settings) {
    for (const auto& [name, value] : settings) set(name, value, name + "=" + value);
}

void FilterParameters::setAssignment(const std::string& assignment) {
    const size_t equals = assignment.find('=');
    if (equals == std::string::npos || equals == 0)
        throw Error("--set '" + assignment + "' is not NAME=VALUE (e.g. --set subpix=0.5)");
    set(assignment.substr(0, equals), assignment.substr(equals + 1), "--set " + assignment);
}

void FilterParameters::requireAllUsed(const std::string& methods, const std::string& accepted) const {
    for (const auto& [name, entry] : entries_)
        if (!entry.used)
            throw Error(entry.origin + ": " + methods + " has no parameter '" + name + "' (" +
                        (accepted.empty() ? std::string("it takes none") : "it takes " + accepted) +
                        "; dejag filter --list-methods)");
}

const ParameterSpec& MethodParameters::declared(const std::string& name) const {
    for (const ParameterSpec& p : spec_.parameters)
        if (p.name == name) return p;
    throw std::logic_error(spec_.name + " reads parameter '" + name +
                           "', which its MethodSpec does not declare");
}

std::string MethodParameters::text(const std::string& name) const {
    const ParameterSpec& spec = declared(name);
    auto it = given_.entries_.find(name);
    if (it == given_.entries_.end()) return spec.defaultValue;
    it->second.used = true;
    return it->second.value;
}

std::string MethodParameters::origin(const std::string& name) const {
    auto it = given_.entries_.find(name);
    return it == given_.entries_.end() ? spec_.name + "'s " + name : it->second.origin;
}

std::string MethodParameters::path(const std::string& name) const {
    const std::string value = text(name);
    return given_.resolve_ ? given_.resolve_(value) : value;
}

int MethodParameters::integer(const std::string& name, int lowest, int highest) const {
    const std::string value = text(name);
    errno = 0;
    char* end = nullptr;
    const long n = std::strtol(value.c_str(), &end, 10);
    if (value.empty() || *end != '\0' || errno == ERANGE || n < lowest || n > highest)
        throw Error(origin(name) + ": " + spec_.name + "'s " + name + " must be an integer from " +
                    std::to_string(lowest) + " to " + std::to_string(highest) + ", not '" + value + "'");
    return int(n);
}

double MethodParameters::number(const std::string& name, double lowest, double highest) const {
    const std::string value = text(name);
    char* end = nullptr;
    const double x = std::strtod(value.c_str(), &end);
    if (value.empty() || *end != '\0' || !std::isfinite(x) || x < lowest || x > highest) {
        std::ostringstream range;
        range << lowest << " to " << highest;
        throw Error(origin(name) + ": " + spec_.name + "'s " + name + " must be a number from " +
                    range.str() + ", not '" + value + "'");
    }
    return x;
}

bool MethodParameters::flag(const std::string& name) const {
    const std::string value = text(name);
    if (value == "true" || value == "on" || value == "yes" || value == "1") return true;
    if (value == "false" || value == "off" || value == "no" || value == "0") return false;
    throw Error(origin(name) + ": " + spec_.name + "'s " + name + " must be true or false, not '" + value +
                "'");
}

// ---- the face ----

void Filter::apply(const Frame& frame, float* out) {
    if (frame.width < 1 || frame.height < 1 || frame.channels < 3 || !frame.colour)
        throw Error(name_ + " needs a colour frame of at least 1x1 pixel with R, G, B");
    for (Buffer b : kBuffers)
        if (contains(needs(), b) && !frame.has(b))
            throw Error(name_ + " needs the " + std::string(bufferName(b)) +
                        " buffer, which the frame lacks");
    const Stopwatch clock;
    process(frame, out);
    figures_.ms = clock.elapsedMs();
}

namespace {

// A filter of filters: each stage filters what the one before wrote (the buffers stay the frame's).
class Chain final : public Filter {
  public:
    Chain(std::string name, std::vector<std::unique_ptr<Filter>> stages)
        : Filter(std::move(name)), stages_(std::move(stages)) {}
    BufferSet needs() const override {
        BufferSet set = 0;
        for (const auto& s : stages_) set |= s->needs();
        return set;
    }
    BufferSet uses() const override {
        BufferSet set = 0;
        for (const auto& s : stages_) set |= s->uses();
        return set;
    }
    bool temporal() const override {
        for (const auto& s : stages_)
            if (s->temporal()) return true;
        return false;
    }
    void reset() override {
        for (auto& s : stages_) s->reset();
    }
    std::vector<const Filter*> stages() const override {
        std::vector<const Filter*> list;
        for (const auto& s : stages_) list.push_back(s.get());
        return list;
    }

  private:
    void process(const Frame& frame, float* out) override {
        const size_t samples = size_t(frame.width) * size_t(frame.height) * size_t(frame.channels);
        if (scratch_.size() < samples) scratch_.resize(samples);
        // Ping-pong so that the last stage writes `out`: with n stages, stage i writes out when n-1-i is
        // even, the scratch buffer when it is odd.
        Frame step = frame;
        const size_t n = stages_.size();
        for (size_t i = 0; i < n; ++i) {
            float* target = (n - 1 - i) % 2 == 0 ? out : scratch_.data();
            stages_[i]->apply(step, target);
            step.colour = target;
        }
        figures_.processedFraction = stages_.back()->figures().processedFraction;
        figures_.extra = stages_.back()->figures().extra;
        figures_.settings = stages_.back()->figures().settings;
    }
    std::vector<std::unique_ptr<Filter>> stages_;
    std::vector<float> scratch_;
};

class NoneFilter final : public Filter {
  public:
    NoneFilter() : Filter("none") {}
    BufferSet needs() const override { return 0; }

  private:
    void process(const Frame& frame, float* out) override {
        if (out == frame.colour) return;
        const int64_t rowFloats = int64_t(frame.width) * frame.channels;
        parallelFor(0, frame.height, 64, [&](int64_t first, int64_t last) {
            std::copy(frame.colour + first * rowFloats, frame.colour + last * rowFloats,
                      out + first * rowFloats);
        });
    }
};

std::string knownMethods() {
    std::string text;
    for (const MethodSpec& m : filterMethods()) text += (text.empty() ? "" : ", ") + m.name;
    return text;
}

}  // namespace

MethodSpec noneMethod() {
    MethodSpec spec;
    spec.name = "none";
    spec.summary = "no anti-aliasing: the frame as it came (the baseline of every comparison)";
    spec.make = [](MethodParameters&) -> std::unique_ptr<Filter> { return std::make_unique<NoneFilter>(); };
    return spec;
}

// The table of methods: one line each.
const std::vector<MethodSpec>& filterMethods() {
    static const std::vector<MethodSpec> table = {
        noneMethod(),     fxaaMethod(),    smaaMethod(),  cnnMethod(),
        taaMethod(false), taaMethod(true), taaHqMethod(), cnnTemporalMethod(),
    };
    return table;
}

const MethodSpec* findMethod(const std::string& name) {
    for (const MethodSpec& m : filterMethods())
        if (m.name == name) return &m;
    return nullptr;
}

std::unique_ptr<Filter> makeFilter(const std::string& methods, const FilterParameters& parameters) {
    const std::vector<std::string> names = splitFields(methods);
    std::vector<std::unique_ptr<Filter>> stages;
    std::string accepted;
    std::set<std::string> listed;
    for (const std::string& name : names) {
        if (name.empty()) throw Error("'" + methods + "' has an empty method (two commas, or one at an end)");
        const MethodSpec* spec = findMethod(name);
        if (!spec) throw Error("'" + name + "' is not a method: the methods are " + knownMethods());
        for (const ParameterSpec& p : spec->parameters)
            if (listed.insert(p.name).second) accepted += (accepted.empty() ? "" : ", ") + p.name;
        MethodParameters view(*spec, parameters);
        stages.push_back(spec->make(view));
    }
    parameters.requireAllUsed(methods, accepted);
    if (stages.size() == 1) return std::move(stages.front());
    return std::make_unique<Chain>(methods, std::move(stages));
}

std::string describeMethods() {
    std::ostringstream text;
    for (const MethodSpec& m : filterMethods()) {
        text << m.name << (m.temporal ? "  (temporal: keeps a history across frames)" : "") << "\n  "
             << m.summary << "\n  needs: " << bufferList(m.needs)
             << "; uses when present: " << bufferList(m.optional) << "\n";
        for (const ParameterSpec& p : m.parameters)
            text << "    " << p.name << " = " << (p.defaultValue.empty() ? "\"\"" : p.defaultValue) << "  "
                 << p.help << "\n";
        text << "\n";
    }
    return text.str();
}

}  // namespace dejag::infer
