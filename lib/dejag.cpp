// libdejag: the public filter face (lib/include/dejag/dejag.h) over infer/filter.h.
#include "dejag/dejag.h"

#include <dlfcn.h>

#include <filesystem>

#include "base/error.h"
#include "infer/filter.h"

namespace dejag::api {
namespace {

namespace fs = std::filesystem;

// The shipped models: a bare name ("dejag-fast") or a models/... path not found as given is looked up
// beside the installed library (PREFIX/lib/../share/dejag/models) and in the source tree it was built from.
std::string resolveModel(const std::string& given) {
    std::error_code error;
    std::string path = given;
    if (!given.empty() && fs::path(given).parent_path().empty() && !fs::path(given).has_extension() &&
        !fs::exists(given, error))
        path = "models/" + given + ".safetensors";
    const fs::path relative(path);
    if (relative.is_absolute() || relative.empty() || *relative.begin() != "models" ||
        fs::exists(relative, error))
        return path;
    std::vector<fs::path> roots;
    Dl_info info{};
    if (dladdr(reinterpret_cast<const void*>(&resolveModel), &info) != 0 && info.dli_fname) {
        const fs::path library = fs::weakly_canonical(fs::path(info.dli_fname), error);
        for (fs::path folder = library.parent_path(); !folder.empty() && folder != folder.root_path();
             folder = folder.parent_path())
            if (fs::is_directory(folder / "share" / "dejag", error)) {
                roots.push_back(folder / "share" / "dejag");
                break;
            }
    }
    roots.push_back(DEJAG_SOURCE_DIR);
    for (const fs::path& root : roots) {
        const fs::path candidate = (root / relative).lexically_normal();
        if (fs::is_regular_file(candidate, error)) return candidate.string();
    }
    return path;
}

std::vector<std::string> bufferNames(infer::BufferSet set) {
    std::vector<std::string> names;
    for (infer::Buffer b : {infer::Buffer::Albedo, infer::Buffer::Depth, infer::Buffer::Motion,
                            infer::Buffer::Ids, infer::Buffer::PreviousDepth, infer::Buffer::Jitter})
        if (set & unsigned(b)) names.push_back(infer::bufferName(b));
    return names;
}

// Every internal error leaves as the public one, its message unchanged.
template <class F>
auto guarded(F&& f) -> decltype(f()) {
    try {
        return f();
    } catch (const dejag::Error& e) {
        throw Error(e.what());
    } catch (const std::bad_alloc&) {
        throw Error("out of memory");
    }
}

}  // namespace

std::string version() {
    return DEJAG_VERSION;
}

std::vector<MethodInfo> methods() {
    std::vector<MethodInfo> list;
    for (const infer::MethodSpec& m : infer::filterMethods()) {
        MethodInfo info{m.name, m.summary, bufferNames(m.needs), {}, m.temporal};
        for (const infer::ParameterSpec& p : m.parameters) info.parameters.push_back(p.name);
        list.push_back(std::move(info));
    }
    return list;
}

struct Filter::Impl {
    std::unique_ptr<infer::Filter> filter;
    infer::Frame frame;
    std::string method;
};

Filter::Filter(const std::string& method, const std::map<std::string, std::string>& parameters)
    : impl_(std::make_unique<Impl>()) {
    guarded([&] {
        infer::FilterParameters given;
        for (const auto& [name, value] : parameters) given.set(name, value, name + "=" + value);
        given.setPathResolver(resolveModel);
        impl_->filter = infer::makeFilter(method, given);
        impl_->method = method;
        return 0;
    });
}

Filter::~Filter() = default;
Filter::Filter(Filter&&) noexcept = default;
Filter& Filter::operator=(Filter&&) noexcept = default;

void Filter::setColour(const float* colour, int width, int height, int channels) {
    if (!colour || width <= 0 || height <= 0 || channels < 3)
        throw Error(
            "setColour: need a non-null image of positive size with at least 3 channels (R, G, B), not " +
            std::to_string(width) + "x" + std::to_string(height) + "x" + std::to_string(channels));
    impl_->frame.colour = colour;
    impl_->frame.width = width, impl_->frame.height = height, impl_->frame.channels = channels;
}

void Filter::setBuffer(const std::string& name, const float* data) {
    infer::Frame& f = impl_->frame;
    if (name == "albedo")
        f.albedo = data;
    else if (name == "depth")
        f.depth = data;
    else if (name == "motion")
        f.motion = data;
    else if (name == "id")
        f.ids = data;
    else if (name == "prevdepth")
        f.previousDepth = data;
    else
        throw Error("setBuffer: no buffer '" + name + "' (albedo, depth, motion, id, prevdepth)");
}

void Filter::setJitter(float x, float y) {
    impl_->frame.hasJitter = true;
    impl_->frame.jitter[0] = x, impl_->frame.jitter[1] = y;
}

void Filter::execute(float* out) {
    if (!impl_->frame.colour) throw Error("execute: no colour set (setColour)");
    if (!out) throw Error("execute: the output is null");
    guarded([&] {
        impl_->filter->apply(impl_->frame, out);
        return 0;
    });
}

void Filter::reset() {
    impl_->filter->reset();
}

const std::string& Filter::method() const {
    return impl_->method;
}
std::vector<std::string> Filter::needs() const {
    return bufferNames(impl_->filter->needs());
}
bool Filter::temporal() const {
    return impl_->filter->temporal();
}
double Filter::lastMilliseconds() const {
    return impl_->filter->figures().ms;
}

}  // namespace dejag::api
