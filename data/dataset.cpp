#include "data/dataset.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <optional>
#include <set>
#include <sstream>

#include "base/communicator.h"
#include "base/error.h"
#include "base/files.h"
#include "base/progress.h"
#include "base/random.h"
#include "base/timer.h"
#include "data/frame_image.h"
#include "data/image.h"
#include "render/gl.h"
#include "render/halton.h"
#include "render/renderer.h"
#include "render/scene.h"

namespace dejag::data {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

uint64_t mix(uint64_t z) {
    return splitMix64(z);
}

// Uniform double in [low, high) from a 64-bit state, advancing it.
double uniform(uint64_t& state, double low, double high) {
    state = mix(state);
    return unitInterval(state, low, high);
}

std::string join(const std::vector<std::string>& items) {
    std::string s;
    for (const std::string& item : items) s += (s.empty() ? "" : ", ") + item;
    return s;
}

}  // namespace

const std::vector<FamilyInfo>& datasetFamilies() {
    static const std::vector<FamilyInfo> families = [] {
        std::vector<FamilyInfo> list;
        for (const render::SceneInfo& scene : render::sceneCatalogue()) {
            auto it = std::find_if(list.begin(), list.end(),
                                   [&](const FamilyInfo& f) { return f.name == scene.family; });
            if (it == list.end()) {
                list.push_back({scene.family, {}, ""});
                it = list.end() - 1;
            }
            it->scenes.push_back(scene.name);
        }
        for (FamilyInfo& f : list) f.description = "scenes: " + join(f.scenes);
        return list;
    }();
    return families;
}

const std::vector<std::string>& defaultTestFamilies() {
    static const std::vector<std::string> names = {"architecture", "foliage"};
    return names;
}

void DatasetSpec::validate() const {
    std::vector<std::string> known;
    for (const FamilyInfo& f : datasetFamilies()) known.push_back(f.name);
    if (families.empty()) throw Error("no families given (" + join(known) + ")");
    for (const std::string& f : families)
        if (std::find(known.begin(), known.end(), f) == known.end())
            throw Error("unknown family '" + f + "' (" + join(known) + ")");
    for (const std::string& f : testFamilies)
        if (std::find(families.begin(), families.end(), f) == families.end())
            throw Error("test family '" + f + "' is not one of the dataset's families (" + join(families) +
                        ")");
    if (testFamilies.size() >= families.size())
        throw Error("every family is held out for testing: nothing is left to train on");
    if (count < 1) throw Error("--count must be at least 1, not " + std::to_string(count));
    if (width < 16 || height < 16 || width > 8192 || height > 8192)
        throw Error("item size " + std::to_string(width) + "x" + std::to_string(height) +
                    " is outside 16..8192");
    if (truthSamples < 1 || truthSamples > 4096)
        throw Error("--truth must be 1..4096 samples, not " + std::to_string(truthSamples));
    if (!(validationFraction >= 0 && validationFraction < 1))
        throw Error("the validation fraction must be in [0, 1)");
    if (sequenceLength < 1 || sequenceLength > 1000)
        throw Error("--sequence-length must be 1..1000 frames, not " + std::to_string(sequenceLength));
    if (!(jitterSpread >= 0 && jitterSpread <= 4))
        throw Error("--jitter-spread must be 0..4 pixels, not " + std::to_string(jitterSpread));
    if (!(closeUps >= 0 && closeUps <= 1))
        throw Error("--close-ups must be a share in [0, 1], not " + std::to_string(closeUps));
    if (samplers.empty()) throw Error("--samplers needs at least one sampler");
    for (size_t i = 0; i < samplers.size(); ++i) {
        render::parseSampler(samplers[i]);  // throws, naming the choices
        if (std::find(samplers.begin(), samplers.begin() + ptrdiff_t(i), samplers[i]) !=
            samplers.begin() + ptrdiff_t(i))
            throw Error("--samplers names '" + samplers[i] + "' twice");
    }
}

json DatasetSpec::toJson() const {
    json j = {{"format", "dejag-dataset-1"},
              {"families", families},
              {"test_families", testFamilies},
              {"count", count},
              {"size", {width, height}},
              {"truth_samples", truthSamples},
              {"adaptive", adaptive},
              {"seed", seed},
              {"validation_fraction", validationFraction}};
    if (sequences())
        j["sequence"] = {{"length", sequenceLength}, {"jitter", "halton16"}, {"jitter_spread", jitterSpread}};
    if (closeUps > 0) j["close_ups"] = closeUps;
    if (samplers != defaultSamplers()) j["samplers"] = samplers;
    return j;
}

DatasetSpec DatasetSpec::fromJson(const json& j) {
    DatasetSpec s;
    try {
        if (j.at("format") != "dejag-dataset-1")
            throw Error("unknown dataset format " + j.at("format").dump());
        s.families = j.at("families").get<std::vector<std::string>>();
        s.testFamilies = j.at("test_families").get<std::vector<std::string>>();
        s.count = j.at("count").get<int>();
        s.width = j.at("size").at(0).get<int>(), s.height = j.at("size").at(1).get<int>();
        s.truthSamples = j.at("truth_samples").get<int>();
        s.adaptive = j.at("adaptive").get<bool>();
        s.seed = j.at("seed").get<uint64_t>();
        s.validationFraction = j.at("validation_fraction").get<double>();
        if (j.contains("close_ups")) s.closeUps = j.at("close_ups").get<double>();
        if (j.contains("samplers")) s.samplers = j.at("samplers").get<std::vector<std::string>>();
        if (j.contains("sequence")) {
            const json& q = j.at("sequence");
            s.sequenceLength = q.at("length").get<int>();
            s.jitterSpread = q.at("jitter_spread").get<double>();
            if (q.at("jitter") != "halton16") throw Error("unknown jitter " + q.at("jitter").dump());
            if (s.sequenceLength < 2) throw Error("a sequence needs at least 2 frames");
        }
    } catch (const json::exception& e) {
        throw Error(std::string("dataset.json is not a dejag dataset description: ") + e.what());
    }
    // (Found by fuzz/fuzz_manifest.cpp: an empty family list divided by zero when items were planned.)
    try {
        s.validate();
    } catch (const Error& e) {
        throw Error(std::string("dataset.json: ") + e.what());
    }
    return s;
}

const char* splitName(Split split) {
    switch (split) {
        case Split::Train:
            return "train";
        case Split::Validation:
            return "validation";
        case Split::Test:
            return "test";
    }
    return "?";
}

ItemPlan planItem(const DatasetSpec& spec, int index) {
    ItemPlan p;
    p.index = index;
    char id[16];
    std::snprintf(id, sizeof id, "%06d", index);
    p.id = id;
    p.family = spec.families[size_t(index) % spec.families.size()];
    p.seed = mix(spec.seed * 0x100000001B3ull ^ uint64_t(index));
    const FamilyInfo& family = *std::find_if(datasetFamilies().begin(), datasetFamilies().end(),
                                             [&](const FamilyInfo& f) { return f.name == p.family; });
    uint64_t state = p.seed;
    p.scene = family.scenes[size_t(uniform(state, 0, double(family.scenes.size())))];
    p.time = std::floor(uniform(state, 1, 100));
    const bool test =
        std::find(spec.testFamilies.begin(), spec.testFamilies.end(), p.family) != spec.testFamilies.end();
    const double draw = double(mix(p.seed ^ 0x5EEDull) >> 11) * 0x1.0p-53;
    p.split = test ? Split::Test : draw < spec.validationFraction ? Split::Validation : Split::Train;
    if (spec.sequences()) {
        // From a state of its own, so that the draws above are those of a single-frame dataset.
        uint64_t moves = p.seed ^ 0x5E9ull;
        const double kind = uniform(moves, 0, 1);
        p.move.kind = kind < 0.15 ? "still" : kind < 0.5 ? "pan" : kind < 0.8 ? "orbit" : "dolly";
        // Log-uniform from a tenth of a pixel to 8 pixels a frame.
        const double speed = std::exp(uniform(moves, std::log(0.1), std::log(8.0)));
        p.move.speed = p.move.kind == "still" ? 0.0 : speed;
        p.move.direction = uniform(moves, 0, 2 * 3.14159265358979323846);
        p.move.timeStep = uniform(moves, 0, 1) < 0.6 ? 1.0 : 0.0;
        const bool cut = uniform(moves, 0, 1) < 0.15 && spec.sequenceLength >= 4;
        const int at = int(uniform(moves, spec.sequenceLength / 4.0, 3.0 * spec.sequenceLength / 4.0));
        p.move.cut = cut ? std::clamp(at, 1, spec.sequenceLength - 1) : -1;
        p.move.jitterStart = int(uniform(moves, 0, 16));
    }
    return p;
}

std::string ItemPlan::sequenceFile(const char* stem, int frame) const {
    char name[64];
    std::snprintf(name, sizeof name, "/%s_%04d.exr", stem, frame);
    return sequenceFolder() + name;
}

std::string fileChecksum(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error("cannot read '" + path + "'");
    uint64_t hash = 0xCBF29CE484222325ull;
    char buffer[1 << 16];
    while (in) {
        in.read(buffer, sizeof buffer);
        for (std::streamsize i = 0; i < in.gcount(); ++i) {
            hash ^= uint8_t(buffer[i]);
            hash *= 0x100000001B3ull;
        }
    }
    char text[17];
    std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(hash));
    return text;
}

// ---- Rendering one item ---------------------------------------------------------------------------------

struct ItemRenderer::Impl {
    std::unique_ptr<render::GlContext> context = render::createOsMesaContext();
};

ItemRenderer::ItemRenderer() : impl_(std::make_unique<Impl>()) {}
ItemRenderer::~ItemRenderer() = default;

namespace {

// The item's variation on its scene: camera orbit, distance and field of view, light, colours; and, for a
// share `closeUps` of the items, a close-up framing.
bool vary(render::Scene& scene, uint64_t seed, double closeUps, double aspect) {
    uint64_t state = seed ^ 0xC0FFEEull;
    const double yaw = uniform(state, -0.35, 0.35), pitch = uniform(state, -0.12, 0.12);
    const double distance = uniform(state, 0.75, 1.25), zoom = uniform(state, 0.85, 1.15);
    // Close-ups from a state of their own, so that every other draw is that of a dataset without them.
    uint64_t closeState = seed ^ 0xC105E0Full;
    const bool closeUp = uniform(closeState, 0, 1) < closeUps;
    const double narrow = std::exp(uniform(closeState, std::log(1.5), std::log(4.5)));
    const double aimX = uniform(closeState, -1, 1), aimY = uniform(closeState, -1, 1);
    const auto camera = scene.camera;
    scene.camera = [=](double t) {
        render::CameraPose pose = camera ? camera(t) : render::CameraPose();
        const render::Vec3 offset = pose.eye - pose.target;
        const render::Vec3 side = render::normalize(render::cross(offset, pose.up));
        const render::Mat4 turn = render::Mat4::rotation(side, pitch) * render::Mat4::rotation(pose.up, yaw);
        pose.eye = pose.target + turn.transformDirection(offset) * distance;
        pose.fovY = std::clamp(pose.fovY * zoom, 0.3, 2.0);
        if (closeUp) {
            // Aim at a point of the full view whose narrowed view stays inside it, then narrow.
            const double halfY = std::tan(pose.fovY / 2), halfX = halfY * aspect, keep = 1 - 1 / narrow;
            const render::Vec3 forward = pose.target - pose.eye;
            const render::Vec3 right = render::normalize(render::cross(forward, pose.up));
            const render::Vec3 up = render::normalize(render::cross(right, forward));
            const double length = render::length(forward);
            pose.target = pose.eye + forward + right * (aimX * keep * halfX * length) +
                          up * (aimY * keep * halfY * length);
            pose.fovY = 2 * std::atan(halfY / narrow);
        }
        return pose;
    };
    scene.lightDirection =
        render::normalize({uniform(state, -1, 1), uniform(state, 0.25, 1), uniform(state, -0.2, 1)});
    const double warmth = uniform(state, -0.08, 0.08);
    scene.lightColour = {1.0 + warmth, 1.0, 1.0 - warmth};
    for (render::SceneObject& o : scene.objects) {
        if (o.material.pattern == render::Pattern::Texture) continue;  // textures keep their colours
        render::Vec3& c = o.material.colour;
        c = {std::clamp(c.x * uniform(state, 0.75, 1.25), 0.02, 1.0),
             std::clamp(c.y * uniform(state, 0.75, 1.25), 0.02, 1.0),
             std::clamp(c.z * uniform(state, 0.75, 1.25), 0.02, 1.0)};
    }
    return closeUp;
}

json fileRecord(const std::string& folder, const std::string& relative) {
    const std::string path = (fs::path(folder) / relative).string();
    return {{"path", relative}, {"bytes", fs::file_size(path)}, {"checksum", fileChecksum(path)}};
}

// Edge pixels of an aliased frame (an ID or a depth jump of > 5 % to the right or below) and its squared
// error against the truth, summed over pixels and channels.
struct FrameMeasures {
    int64_t edges = 0;
    double squared = 0;
};
FrameMeasures measureFrame(const Image& input, const Image& truth) {
    FrameMeasures m;
    const int id = input.findChannel("id.ID"), depth = input.findChannel("depth.Z"),
              r = input.findChannel("R");
    for (int y = 0; y < input.height; ++y)
        for (int x = 0; x < input.width; ++x) {
            bool edge = false;
            for (const auto& [dx, dy] : {std::pair{1, 0}, std::pair{0, 1}}) {
                if (x + dx >= input.width || y + dy >= input.height) continue;
                const float d0 = input.at(x, y, depth), d1 = input.at(x + dx, y + dy, depth);
                edge = edge || input.at(x, y, id) != input.at(x + dx, y + dy, id) ||
                       std::abs(d0 - d1) > 0.05f * std::min(d0, d1);
            }
            m.edges += edge;
            for (int c = 0; c < 3; ++c) {
                const double d = double(input.at(x, y, r + c)) - double(truth.at(x, y, c));
                m.squared += d * d;
            }
        }
    return m;
}

// What a frame's motion vectors say (docs/data.md): the speeds, the pixels that move, and the pixels
// whose history is disoccluded — its place in the previous frame (p - motion, nearest pixel) is off
// screen, or its depth lies more than 10 % outside the previous depths of the 3x3 there.
struct MotionMeasures {
    double speedSum = 0, speedMax = 0;
    int64_t moving = 0, disoccluded = 0, pixels = 0;
    void add(const Image& frame) {
        const int mx = frame.findChannel("motion.X"), my = frame.findChannel("motion.Y"),
                  depth = frame.findChannel("depth.Z"), previous = frame.findChannel("prevdepth.Z");
        const int W = frame.width, H = frame.height;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                const double vx = frame.at(x, y, mx), vy = frame.at(x, y, my);
                const double speed = std::sqrt(vx * vx + vy * vy);
                speedSum += speed, speedMax = std::max(speedMax, speed);
                moving += speed > 0.01;
                ++pixels;
                const double px = std::floor(x + 0.5 - vx), py = std::floor(y + 0.5 - vy);
                bool rejected = !(px >= 0 && px < W && py >= 0 && py < H);
                if (!rejected) {
                    float lo = 1e30f, hi = 0;
                    for (int dy = -1; dy <= 1; ++dy)
                        for (int dx = -1; dx <= 1; ++dx) {
                            const float d = frame.at(std::clamp(int(px) + dx, 0, W - 1),
                                                     std::clamp(int(py) + dy, 0, H - 1), previous);
                            lo = std::min(lo, d), hi = std::max(hi, d);
                        }
                    const float d = frame.at(x, y, depth);
                    rejected = d < 0.9f * lo || d > 1.1f * hi;
                }
                disoccluded += rejected;
            }
    }
};

// The camera of frame `frame` of a sequence: the item's own view (`base`, at the scene time of that
// frame) moved as `move` says for the frames since its shot began. The second shot of a cut looks from
// another side, at another scene time.
render::CameraPose movedCamera(const std::function<render::CameraPose(double)>& base, const ItemPlan& plan,
                               int height, double frame) {
    const ItemPlan::Move& move = plan.move;
    const bool second = move.cut >= 0 && frame >= move.cut;
    const double since = second ? frame - move.cut : frame;
    const double sceneTime = plan.time + move.timeStep * frame + (second ? 37.0 : 0.0);
    render::CameraPose pose = base ? base(sceneTime) : render::CameraPose();
    if (second) {
        const render::Vec3 offset = pose.eye - pose.target;
        const double turn = std::cos(move.direction) >= 0 ? 0.6 : -0.6;
        pose.eye = pose.target + render::Mat4::rotation(pose.up, turn).transformDirection(offset);
    }
    const render::Vec3 offset = pose.eye - pose.target;
    const double distance = render::length(offset);
    const double pixel = 2 * distance * std::tan(pose.fovY / 2) / height;  // at the target's distance
    const render::Vec3 forward = render::normalize(pose.target - pose.eye);
    const render::Vec3 right = render::normalize(render::cross(forward, pose.up));
    const render::Vec3 up = render::cross(right, forward);
    const double travel = move.speed * pixel * since;
    const double way = std::cos(move.direction) >= 0 ? 1.0 : -1.0;
    if (move.kind == "pan") {
        const render::Vec3 shift =
            (right * std::cos(move.direction) + up * std::sin(move.direction)) * travel;
        pose.eye = pose.eye + shift, pose.target = pose.target + shift;
    } else if (move.kind == "orbit") {
        const double angle = way * travel / distance;
        pose.eye = pose.target + (-forward * std::cos(angle) + right * std::sin(angle)) * distance;
    } else if (move.kind == "dolly") {
        // `speed` pixels a frame at the top and bottom edges: the distance changes by speed / (H / 2)
        // of itself a frame, towards the target or away, never nearer than 0.3 of it.
        const double scale = std::max(0.3, 1.0 - way * move.speed / (height / 2.0) * since);
        pose.eye = pose.target + offset * scale;
    }
    return pose;
}

// The fields of a manifest record every item has: what it is, its camera (at `pose`), texture sampler,
// light and sample counts.
json itemRecord(const DatasetSpec& spec, const ItemPlan& plan, const render::Scene& scene,
                const render::SceneOptions& options, const render::CameraPose& pose, int truthSamples,
                int64_t truthTileSamples) {
    auto vec = [](const render::Vec3& v) { return json{v.x, v.y, v.z}; };
    return {{"index", plan.index},
            {"id", plan.id},
            {"family", plan.family},
            {"scene", plan.scene},
            {"seed", plan.seed},
            {"split", splitName(plan.split)},
            {"time", plan.time},
            {"size", {spec.width, spec.height}},
            {"camera",
             {{"eye", vec(pose.eye)},
              {"target", vec(pose.target)},
              {"up", vec(pose.up)},
              {"fov_y", pose.fovY},
              {"tilted", options.tiltedCamera}}},
            // What the scene reads its textures with (a scene may keep its own), "none" without any.
            {"sampler", scene.textures.empty() ? json("none") : json(render::samplerName(scene.sampler))},
            {"light", vec(scene.lightDirection)},
            {"samples",
             {{"input", 1},
              {"truth", truthSamples},
              {"truth_tile_samples", truthTileSamples},
              {"adaptive", spec.adaptive}}}};
}

// A sequence item (spec.sequences()): its K frames, their truths and render.json; its manifest record.
json renderSequence(const render::GlContext& context, const DatasetSpec& spec, const ItemPlan& plan,
                    const std::string& folder, render::Scene scene, const render::SceneOptions& options) {
    const ItemPlan::Move& move = plan.move;
    const int K = spec.sequenceLength;
    // The renderer's time is the frame number; the scene's own animation and the camera follow from it.
    auto sceneTime = [plan](double frame) {
        const bool second = plan.move.cut >= 0 && frame >= plan.move.cut;
        return plan.time + plan.move.timeStep * frame + (second ? 37.0 : 0.0);
    };
    for (render::SceneObject& o : scene.objects)
        if (o.transform)
            o.transform = [f = o.transform, sceneTime](double frame) { return f(sceneTime(frame)); };
    scene.camera = [base = scene.camera, plan, H = spec.height](double frame) {
        return movedCamera(base, plan, H, frame);
    };

    render::Renderer renderer(context, scene, spec.width, spec.height);
    render::TruthOptions truthOptions;
    truthOptions.samples = spec.truthSamples;
    truthOptions.adaptive = spec.adaptive;
    fs::create_directories(fs::path(folder) / plan.sequenceFolder());
    auto vec = [](const render::Vec3& v) { return json{v.x, v.y, v.z}; };
    json frames = json::array(), files = json::object();
    FrameMeasures measures;
    MotionMeasures motion;
    int truthSamples = 0;
    int64_t truthTileSamples = 0;
    for (int k = 0; k < K; ++k) {
        const bool cut = k == move.cut;
        const unsigned point = unsigned(move.jitterStart + k);
        render::FrameRequest request;
        request.time = k;
        request.previousTime = cut ? k : k - 1;  // a cut: no previous frame of this view
        request.jitter = render::jitterPixels(point % 16, spec.jitterSpread);
        request.previousJitter = render::jitterPixels((point + 15) % 16, spec.jitterSpread);
        request.buffers = render::BufferSet::parse("color,albedo,depth,motion,id,prevdepth");
        const Image input = imageFromFrame(renderer.render(request));
        render::TruthStats stats;
        const Image truth = imageFromFrame(renderer.renderTruth(k, truthOptions, &stats));
        truthSamples = std::max(truthSamples, stats.samples);
        truthTileSamples += stats.tileSamples;
        const FrameMeasures m = measureFrame(input, truth);
        measures.edges += m.edges, measures.squared += m.squared;
        if (!cut) motion.add(input);
        const std::string frameFile = plan.sequenceFile("frame", k),
                          truthFile = plan.sequenceFile("truth", k);
        writeImage((fs::path(folder) / frameFile).string(), input);
        writeImage((fs::path(folder) / truthFile).string(), truth);
        char key[32];
        std::snprintf(key, sizeof key, "frame_%04d", k);
        files[key] = fileRecord(folder, frameFile);
        std::snprintf(key, sizeof key, "truth_%04d", k);
        files[key] = fileRecord(folder, truthFile);
        const render::CameraPose pose = scene.cameraAt(k);
        frames.push_back(
            {{"index", k},
             {"time", k},
             {"scene_time", sceneTime(k)},
             {"file", fs::path(frameFile).filename().string()},
             {"truth", {{"file", fs::path(truthFile).filename().string()}, {"samples", stats.samples}}},
             {"jitter_pixels", {request.jitter.x, -request.jitter.y}},
             {"cut", cut},
             {"camera",
              {{"eye", vec(pose.eye)},
               {"target", vec(pose.target)},
               {"up", vec(pose.up)},
               {"fov_y_degrees", pose.fovY * 180.0 / render::kPi}}}});
    }
    const json moveJson = {
        {"kind", move.kind},          {"speed", move.speed}, {"direction", move.direction},
        {"time_step", move.timeStep}, {"cut", move.cut},     {"jitter_start", move.jitterStart}};
    // Beside the frames, what dejag filter reads of a dejag render folder (the jitter of each frame, the
    // far plane, the cuts) and what the frames are.
    json sidecar = {
        {"scene", plan.scene},
        {"family", plan.family},
        {"size", {spec.width, spec.height}},
        {"seed", plan.seed},
        {"jitter",
         {{"mode", "halton16"},
          {"spread", spec.jitterSpread},
          {"start", move.jitterStart},
          {"sequence", "Halton(2,3), base-3 digits 1<->2 scrambled"}}},
        {"move", moveJson},
        {"channels", render::BufferSet::all().channelNames()},
        {"depth_far", scene.far},
        {"cuts", move.cut >= 0 ? json::array({move.cut}) : json::array()},
        {"truth", {{"samples", spec.truthSamples}, {"adaptive", spec.adaptive}, {"filter", "box"}}},
        {"frames", frames}};
    const std::string renderFile = plan.sequenceFolder() + "/render.json";
    writeTextFileAtomically((fs::path(folder) / renderFile).string(), sidecar.dump(2) + "\n");
    files["render"] = fileRecord(folder, renderFile);

    const double pixels = double(spec.width) * double(spec.height) * K;
    const double mse = measures.squared / (3.0 * pixels);
    const double counted = std::max<int64_t>(motion.pixels, 1);
    json record = itemRecord(spec, plan, scene, options, scene.cameraAt(0), truthSamples, truthTileSamples);
    record.update({{"edge_fraction", double(measures.edges) / pixels},
                   {"aliased_psnr", mse > 0 ? 10 * std::log10(1.0 / mse) : 999.0},
                   {"sequence", {{"length", K}, {"move", moveJson}}},
                   {"motion",
                    {{"mean_speed", motion.speedSum / counted},
                     {"max_speed", motion.speedMax},
                     {"moving_fraction", double(motion.moving) / counted},
                     {"disoccluded_fraction", double(motion.disoccluded) / counted}}},
                   {"files", files}});
    return record;
}

}  // namespace

json ItemRenderer::render(const DatasetSpec& spec, const ItemPlan& plan, const std::string& folder) {
    uint64_t state = plan.seed ^ 0x0B7Eull;
    render::SceneOptions options;
    options.seed = plan.seed;
    options.tiltedCamera = uniform(state, 0, 1) < 0.4;
    // One of the spec's samplers (by default point, bilinear or trilinear: llvmpipe's anisotropic
    // filtering costs a minute per truth on grazing, tilted planes). One draw whatever the list, so the
    // items' other choices do not depend on it.
    const double samplerDraw = uniform(state, 0, double(spec.samplers.size()));
    options.sampler =
        render::parseSampler(spec.samplers[std::min(size_t(samplerDraw), spec.samplers.size() - 1)]);
    const char* textures[] = {"checker", "bricks", "stripes", "text", "noise"};
    options.texture = textures[int(uniform(state, 0, 5))];
    render::Scene scene = render::buildScene(plan.scene, options);
    const bool closeUp = vary(scene, plan.seed, spec.closeUps, double(spec.width) / double(spec.height));

    if (spec.sequences()) {
        json record = renderSequence(*impl_->context, spec, plan, folder, std::move(scene), options);
        if (closeUp) record["close_up"] = true;
        return record;
    }

    render::Renderer renderer(*impl_->context, scene, spec.width, spec.height);
    render::FrameRequest request;
    request.time = plan.time, request.previousTime = plan.time - 1;
    request.buffers = render::BufferSet::parse("color,albedo,depth,motion,id");
    const Image input = imageFromFrame(renderer.render(request));
    render::TruthOptions truthOptions;
    truthOptions.samples = spec.truthSamples;
    truthOptions.adaptive = spec.adaptive;
    render::TruthStats stats;
    const Image truth = imageFromFrame(renderer.renderTruth(plan.time, truthOptions, &stats));

    // Edge pixels and the aliased frame's PSNR.
    const FrameMeasures measures = measureFrame(input, truth);
    const int64_t edges = measures.edges;
    const double mse = measures.squared / (3.0 * double(input.pixelCount()));

    fs::create_directories(fs::path(folder) / "items" / plan.family);
    writeImage((fs::path(folder) / plan.inputFile()).string(), input);
    writeImage((fs::path(folder) / plan.truthFile()).string(), truth);
    json record =
        itemRecord(spec, plan, scene, options, scene.cameraAt(plan.time), stats.samples, stats.tileSamples);
    if (closeUp) record["close_up"] = true;
    record.update({{"edge_fraction", double(edges) / double(input.pixelCount())},
                   {"aliased_psnr", mse > 0 ? 10 * std::log10(1.0 / mse) : 999.0},
                   {"files",
                    {{"input", fileRecord(folder, plan.inputFile())},
                     {"truth", fileRecord(folder, plan.truthFile())}}}});
    return record;
}

// ---- Manifest, generation -------------------------------------------------------------------------------

namespace {

// What every reader of the manifest relies on (the record makeRecord() writes); empty if r has it all.
std::string recordProblem(const json& r) {
    if (!r.is_object()) return "not a JSON object";
    auto has = [&](const json& o, const char* key, bool (json::*is)() const) {
        const auto it = o.find(key);
        return it != o.end() && ((*it).*is)();
    };
    if (!has(r, "index", &json::is_number_integer) || r["index"].get<int64_t>() < 0 ||
        r["index"].get<int64_t>() > INT32_MAX)
        return "'index' is not an item number";
    for (const char* key : {"id", "family", "split"})
        if (!has(r, key, &json::is_string)) return std::string("'") + key + "' is not a string";
    for (const char* key : {"edge_fraction", "aliased_psnr"})
        if (!has(r, key, &json::is_number)) return std::string("'") + key + "' is not a number";
    if (!has(r, "size", &json::is_array) || r["size"].size() != 2 || !r["size"][0].is_number_integer() ||
        !r["size"][1].is_number_integer() || r["size"][0].get<int64_t>() < 1 ||
        r["size"][1].get<int64_t>() < 1 || r["size"][0].get<int64_t>() > 65536 ||
        r["size"][1].get<int64_t>() > 65536)
        return "'size' is not [width, height]";
    if (!has(r, "files", &json::is_object) || r["files"].empty()) return "'files' is not an object";
    if (r.contains("sequence")) {
        const json& q = r["sequence"];
        if (!q.is_object() || !has(q, "length", &json::is_number_integer) ||
            !has(q, "move", &json::is_object) || !has(q["move"], "kind", &json::is_string) ||
            !has(q["move"], "cut", &json::is_number_integer))
            return "'sequence' needs length and move (kind, cut)";
        if (!has(r, "motion", &json::is_object)) return "'motion' is not an object";
        for (const char* key : {"mean_speed", "max_speed", "moving_fraction", "disoccluded_fraction"})
            if (!has(r["motion"], key, &json::is_number))
                return std::string("'motion.") + key + "' is not a number";
    }
    // A single frame has its input and truth; a sequence (a record with "sequence") its frames, their
    // truths and render.json, by any names.
    if (!r.contains("sequence"))
        for (const char* which : {"input", "truth"})
            if (!has(r["files"], which, &json::is_object))
                return std::string("'files.") + which + "' is missing";
    for (const auto& [which, f] : r["files"].items()) {
        if (!f.is_object() || !has(f, "path", &json::is_string) ||
            !has(f, "bytes", &json::is_number_unsigned) || !has(f, "checksum", &json::is_string))
            return "'files." + which + "' needs path, bytes and checksum";
        const fs::path path(f["path"].get<std::string>());
        if (path.empty() || path.is_absolute() ||
            std::any_of(path.begin(), path.end(), [](const fs::path& part) { return part == ".."; }))
            return "'files." + which + ".path' is not a path inside the dataset";
    }
    return {};
}

}  // namespace

std::vector<json> readManifest(const std::string& folder) {
    std::vector<json> records;
    std::ifstream in(fs::path(folder) / "manifest.jsonl");
    std::string line;
    for (int number = 1; std::getline(in, line); ++number) {
        if (line.empty()) continue;
        json record;
        try {
            record = json::parse(line);
        } catch (const json::exception&) {
            if (in.peek() == EOF) break;  // an interrupted last append
            throw Error("manifest.jsonl in '" + folder + "' has a corrupt line " + std::to_string(number) +
                        ": " + line.substr(0, 60));
        }
        const std::string problem = recordProblem(record);
        if (!problem.empty())
            throw Error("manifest.jsonl in '" + folder + "', line " + std::to_string(number) + ": " +
                        problem);
        records.push_back(std::move(record));
    }
    return records;
}

namespace {

void writeManifest(const std::string& folder, std::vector<json> records) {
    std::sort(records.begin(), records.end(),
              [](const json& a, const json& b) { return a["index"].get<int>() < b["index"].get<int>(); });
    std::string text;
    for (const json& r : records) text += r.dump() + "\n";
    writeTextFileAtomically((fs::path(folder) / "manifest.jsonl").string(), text);
}

// The records the ranks of a job appended (manifest.rank-R.jsonl), read as the manifest is.
std::vector<json> readRankManifests(const std::string& folder) {
    std::vector<json> records;
    for (const auto& entry : fs::directory_iterator(folder)) {
        const std::string name = entry.path().filename().string();
        if (name.rfind("manifest.rank-", 0) != 0 || entry.path().extension() != ".jsonl") continue;
        std::ifstream in(entry.path());
        std::string line;
        while (std::getline(in, line)) {
            const json record = json::parse(line, nullptr, false);  // (an interrupted last append: skipped)
            if (record.is_object() && record.contains("index")) records.push_back(record);
        }
    }
    return records;
}
void removeRankManifests(const std::string& folder) {
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(folder))
        if (entry.path().filename().string().rfind("manifest.rank-", 0) == 0) fs::remove(entry.path(), ec);
}

bool filesPresent(const std::string& folder, const json& record) {
    for (const json& f : record["files"]) {
        const fs::path path = fs::path(folder) / f["path"].get<std::string>();
        std::error_code ec;
        if (!fs::is_regular_file(path, ec) || fs::file_size(path, ec) != f["bytes"].get<uintmax_t>())
            return false;
    }
    return true;
}

// The worker loop of one child process: render its share and report each record on `out`.
[[noreturn]] void runWorker(const DatasetSpec& spec, const std::string& folder, const std::vector<int>& items,
                            int out) {
    int status = 0;
    try {
        ItemRenderer renderer;
        for (int index : items) {
            const std::string line =
                "item " + renderer.render(spec, planItem(spec, index), folder).dump() + "\n";
            if (::write(out, line.data(), line.size()) != ssize_t(line.size())) _exit(3);
        }
    } catch (const std::exception& e) {
        std::string line = std::string("error ") + e.what();
        std::replace(line.begin(), line.end(), '\n', ' ');
        line += "\n";
        [[maybe_unused]] const ssize_t written = ::write(out, line.data(), line.size());
        status = 1;
    }
    ::close(out);
    _exit(status);
}

}  // namespace

GenerateResult generateDataset(const DatasetSpec& spec, const std::string& folder,
                               const GenerateOptions& options) {
    spec.validate();
    if (options.workers < 1 || options.workers > 64) throw Error("--workers must be 1..64");
    const Stopwatch clock;
    // A job of several processes (dejag-mpi, docs/mpi.md): rank 0 prepares the folder and holds its lock;
    // each rank renders every size-th pending item and appends its records to a manifest of its own,
    // which rank 0 merges into manifest.jsonl at the end (or, after a rank died, when the job is run again).
    Communicator& comm = communicator();
    std::optional<FolderLock> lock;
    std::map<int, json> done;
    together([&] {
        if (comm.rank() != 0) return;
        std::error_code ec;
        fs::create_directories(folder, ec);
        if (ec || !fs::is_directory(folder) || ::access(folder.c_str(), W_OK) != 0)
            throw Error("cannot write to the dataset folder '" + folder + "'");
        lock.emplace(folder, "a dataset generation");
        const fs::path description = fs::path(folder) / "dataset.json";
        if (fs::exists(description)) {
            std::ifstream in(description);
            json existing;
            try {
                existing = json::parse(in);
            } catch (const json::exception&) {
                throw Error("'" + description.string() +
                            "' is corrupt; the folder is not a dataset dejag can resume");
            }
            if (existing != spec.toJson())
                throw Error("'" + folder + "' holds a different dataset (" + existing.dump() +
                            "); choose another folder or repeat its arguments");
        } else {
            for (const auto& entry : fs::directory_iterator(folder))
                if (entry.path().filename() != FolderLock::kFileName)
                    throw Error("'" + folder + "' is not empty and holds no dataset.json");
            writeTextFileAtomically(description.string(), spec.toJson().dump(2) + "\n");
        }
        // Temporary files of an interrupted run.
        if (fs::exists(fs::path(folder) / "items"))
            for (const auto& entry : fs::recursive_directory_iterator(fs::path(folder) / "items"))
                if (entry.is_regular_file() &&
                    entry.path().filename().string().find(".tmp-") != std::string::npos)
                    fs::remove(entry.path(), ec);
        // The manifest so far, with the records of the ranks of an interrupted job, cleaned of partial or
        // stale records, before appending.
        std::vector<json> records = readManifest(folder);
        for (json& r : readRankManifests(folder)) records.push_back(std::move(r));
        for (json& r : records) {
            const int index = r.value("index", -1);
            if (index >= 0 && index < spec.count && filesPresent(folder, r)) done[index] = std::move(r);
        }
        std::vector<json> kept;
        for (auto& [index, r] : done) kept.push_back(r);
        writeManifest(folder, kept);
        removeRankManifests(folder);
    });
    if (comm.rank() != 0)  // (the manifest rank 0 has just cleaned)
        for (json& r : readManifest(folder)) {
            const int index = r.value("index", -1);
            done[index] = std::move(r);
        }
    std::vector<int> pending;
    for (int i = 0, k = 0; i < spec.count; ++i)
        if (!done.count(i) && k++ % comm.size() == comm.rank()) pending.push_back(i);
    GenerateResult result;
    result.skipped = int(done.size());
    std::vector<json> records;
    for (auto& [index, r] : done) records.push_back(r);
    const std::string manifestName =
        comm.size() > 1 ? "manifest.rank-" + std::to_string(comm.rank()) + ".jsonl" : "manifest.jsonl";

    if (!pending.empty()) {
        const int workers = std::min<int>(options.workers, int(pending.size()));
        std::vector<pid_t> children;
        std::vector<int> pipes;
        for (int k = 0; k < workers; ++k) {
            std::vector<int> share;
            for (size_t i = size_t(k); i < pending.size(); i += size_t(workers)) share.push_back(pending[i]);
            int fds[2];
            if (::pipe(fds) != 0) throw Error("cannot create a pipe for a worker");
            // The worker's command line, built before the fork: between fork and exec the child only
            // closes descriptors and calls execv (what is safe in the child of a threaded process).
            std::vector<std::string> argvStrings;
            std::vector<char*> argv;
            if (!options.workerCommand.empty()) {
                std::string items;
                for (int index : share) items += (items.empty() ? "" : ",") + std::to_string(index);
                argvStrings = options.workerCommand;
                argvStrings.insert(argvStrings.end(), {"--folder", folder, "--items", items, "--result-fd",
                                                       std::to_string(fds[1])});
                for (std::string& a : argvStrings) argv.push_back(a.data());
                argv.push_back(nullptr);
            }
            std::fflush(nullptr);
            const pid_t parent = ::getpid();
            const pid_t pid = ::fork();
            if (pid < 0) throw Error("cannot start a worker process");
            if (pid == 0) {
                // A worker ends with its parent (SIGTERM, so it removes its temporary files), whatever
                // ended the parent, SIGKILL included; and if the parent died before this line, at once.
                ::prctl(PR_SET_PDEATHSIG, SIGTERM);
                if (::getppid() != parent) _exit(1);
                ::close(fds[0]);
                for (int other : pipes) ::close(other);
                if (argv.empty()) runWorker(spec, folder, share, fds[1]);
                ::execv(argv[0], argv.data());
                static const char kFailed[] = "error cannot start the dataset worker program\n";
                [[maybe_unused]] const ssize_t written = ::write(fds[1], kFailed, sizeof kFailed - 1);
                _exit(127);
            }
            ::close(fds[1]);
            children.push_back(pid);
            pipes.push_back(fds[0]);
        }
        const int manifest =
            ::open((fs::path(folder) / manifestName).c_str(), O_WRONLY | O_APPEND | O_CREAT, 0644);
        if (manifest < 0) throw Error("cannot append to the manifest in '" + folder + "'");
        Progress progress("data generate", int64_t(pending.size()), options.quiet || comm.rank() != 0);
        std::vector<std::string> buffers(pipes.size());
        std::vector<bool> open(pipes.size(), true);
        std::string firstError;
        size_t openCount = pipes.size();
        while (openCount > 0) {
            std::vector<pollfd> fds;
            std::vector<size_t> which;
            for (size_t k = 0; k < pipes.size(); ++k)
                if (open[k]) fds.push_back({pipes[k], POLLIN, 0}), which.push_back(k);
            if (::poll(fds.data(), fds.size(), -1) < 0) continue;
            for (size_t f = 0; f < fds.size(); ++f) {
                if (!(fds[f].revents & (POLLIN | POLLHUP | POLLERR))) continue;
                const size_t k = which[f];
                char chunk[8192];
                const ssize_t n = ::read(pipes[k], chunk, sizeof chunk);
                if (n <= 0) {
                    open[k] = false, --openCount;
                    ::close(pipes[k]);
                    continue;
                }
                buffers[k].append(chunk, size_t(n));
                size_t newline;
                while ((newline = buffers[k].find('\n')) != std::string::npos) {
                    const std::string line = buffers[k].substr(0, newline);
                    buffers[k].erase(0, newline + 1);
                    if (line.rfind("item ", 0) == 0) {
                        const std::string record = line.substr(5) + "\n";
                        if (::write(manifest, record.data(), record.size()) != ssize_t(record.size()))
                            throw Error("cannot append to the manifest in '" + folder + "'");
                        records.push_back(json::parse(line.substr(5)));
                        ++result.rendered;
                        if (comm.rank() == options.killRank && result.rendered == options.killAfterItems)
                            ::kill(::getpid(), SIGKILL);
                        progress.advance(1, records.back()["scene"].get<std::string>());
                    } else if (line.rfind("error ", 0) == 0 && firstError.empty()) {
                        firstError = line.substr(6);
                    }
                }
            }
        }
        ::close(manifest);
        bool crashed = false;
        for (pid_t pid : children) {
            int status = 0;
            ::waitpid(pid, &status, 0);
            crashed = crashed || !WIFEXITED(status) || WEXITSTATUS(status) != 0;
        }
        if (!firstError.empty()) throw Error(firstError);
        if (crashed) throw Error("a dataset worker died; run the same command again to resume");
    }
    if (comm.size() == 1) {
        writeManifest(folder, records);
    } else {
        // Every rank done: rank 0 merges the ranks' records; the job's count of rendered items.
        const double mine = result.rendered;
        std::vector<double> rendered(size_t(comm.size()));
        comm.allGather(&mine, 1, rendered.data());
        result.rendered = int(std::accumulate(rendered.begin(), rendered.end(), 0.0));
        if (comm.rank() == 0) {
            std::map<int, json> all;
            for (std::vector<json> part : {readManifest(folder), readRankManifests(folder)})
                for (json& r : part) {
                    const int index = r.value("index", -1);  // (before the move: json's = takes a copy)
                    all[index] = std::move(r);
                }
            std::vector<json> merged;
            for (auto& [index, r] : all) merged.push_back(std::move(r));
            writeManifest(folder, merged);
            removeRankManifests(folder);
        }
    }
    result.seconds = clock.elapsedMs() / 1000.0;
    return result;
}

void runDatasetWorker(const std::string& folder, const std::vector<int>& items, int resultFd) {
    DatasetSpec spec;
    try {
        std::ifstream in(fs::path(folder) / "dataset.json");
        spec = DatasetSpec::fromJson(json::parse(in));
    } catch (const std::exception& e) {
        const std::string line = std::string("error dataset worker: ") + e.what() + "\n";
        [[maybe_unused]] const ssize_t written = ::write(resultFd, line.data(), line.size());
        _exit(1);
    }
    runWorker(spec, folder, items, resultFd);
}

// ---- Verify, stats --------------------------------------------------------------------------------------

VerifyReport verifyDataset(const std::string& folder) {
    VerifyReport report;
    const fs::path description = fs::path(folder) / "dataset.json";
    if (!fs::exists(description)) throw Error("'" + folder + "' is not a dataset (no dataset.json)");
    std::ifstream in(description);
    const DatasetSpec spec = DatasetSpec::fromJson(json::parse(in, nullptr, false));
    const std::vector<json> records = readManifest(folder);
    report.items = int(records.size());
    std::set<std::string> referenced;
    std::set<int> indices;
    for (const json& r : records) {
        const std::string id = r.value("id", std::string("?"));
        const int index = r.value("index", -1);
        if (!indices.insert(index).second) report.problems.push_back("item " + id + ": listed twice");
        if (index < 0 || index >= spec.count)
            report.problems.push_back("item " + id + ": index outside the dataset");
        const ItemPlan plan = planItem(spec, std::max(0, index));
        if (r.value("family", std::string()) != plan.family ||
            r.value("split", std::string()) != splitName(plan.split))
            report.problems.push_back("item " + id + ": family or split differs from the dataset's plan");
        if (r.contains("sequence") != spec.sequences())
            report.problems.push_back("item " + id +
                                      (spec.sequences() ? ": a single frame in a dataset of sequences"
                                                        : ": a sequence in a dataset of single frames"));
        for (const json& f : r["files"]) {
            const std::string relative = f.value("path", std::string());
            referenced.insert(relative);
            const fs::path path = fs::path(folder) / relative;
            std::error_code ec;
            if (!fs::is_regular_file(path, ec)) {
                report.problems.push_back("item " + id + ": missing " + relative);
                continue;
            }
            if (fs::file_size(path, ec) != f.value("bytes", uintmax_t(0))) {
                report.problems.push_back(
                    "item " + id + ": " + relative + " has " + std::to_string(fs::file_size(path, ec)) +
                    " bytes, the manifest says " + std::to_string(f.value("bytes", uintmax_t(0))));
                continue;
            }
            if (fileChecksum(path.string()) != f.value("checksum", std::string()))
                report.problems.push_back("item " + id + ": " + relative + " checksum differs (corrupt)");
        }
    }
    if (int(records.size()) < spec.count)
        report.problems.push_back(std::to_string(spec.count - int(records.size())) + " of " +
                                  std::to_string(spec.count) + " items are not generated yet");
    if (fs::exists(fs::path(folder) / "items"))
        for (const auto& entry : fs::recursive_directory_iterator(fs::path(folder) / "items")) {
            if (!entry.is_regular_file()) continue;
            const std::string relative = fs::relative(entry.path(), folder).string();
            if (!referenced.count(relative)) report.problems.push_back("extra file " + relative);
        }
    return report;
}

json datasetStats(const std::string& folder) {
    const std::vector<json> records = readManifest(folder);
    if (records.empty()) throw Error("'" + folder + "' has no generated items (manifest.jsonl)");
    std::map<std::string, std::map<std::string, int>> counts;  // family -> split -> items
    std::map<std::string, std::vector<double>> psnr;           // family -> aliased PSNRs
    std::map<std::string, double> edges;
    json flat = json::array();
    // Sequences: per family (and "all") the sums and counts behind the motion statistics.
    struct MotionTally {
        int sequences = 0, cuts = 0;
        double meanSpeed = 0, maxSpeed = 0, moving = 0, disoccluded = 0;
        std::map<std::string, int> moves;
        void add(const json& r) {
            ++sequences;
            const json& m = r["motion"];
            meanSpeed += m["mean_speed"].get<double>(),
                maxSpeed = std::max(maxSpeed, m["max_speed"].get<double>());
            moving += m["moving_fraction"].get<double>(),
                disoccluded += m["disoccluded_fraction"].get<double>();
            cuts += r["sequence"]["move"]["cut"].get<int>() >= 0;
            ++moves[r["sequence"]["move"]["kind"].get<std::string>()];
        }
        json toJson() const {
            const double n = std::max(sequences, 1);
            return {{"sequences", sequences},
                    {"mean_speed", meanSpeed / n},
                    {"max_speed", maxSpeed},
                    {"moving_fraction", moving / n},
                    {"disoccluded_fraction", disoccluded / n},
                    {"cuts", cuts},
                    {"moves", moves}};
        }
    };
    std::map<std::string, MotionTally> motion;
    MotionTally allMotion;
    // The texture samplers the items' scenes read with (records without textures say "none").
    std::map<std::string, std::map<std::string, int>> samplers;
    std::map<std::string, int> allSamplers;
    for (const json& r : records) {
        const std::string family = r["family"], split = r["split"];
        ++counts[family][split];
        if (const auto it = r.find("sampler"); it != r.end() && it->is_string() && *it != "none")
            ++samplers[family][it->get<std::string>()], ++allSamplers[it->get<std::string>()];
        if (r.contains("sequence")) motion[family].add(r), allMotion.add(r);
        if (r["aliased_psnr"].get<double>() >= kFlatItemPsnr)
            flat.push_back(
                {{"id", r["id"]}, {"family", family}, {"split", split}, {"aliased_psnr", r["aliased_psnr"]}});
        psnr[family].push_back(r["aliased_psnr"].get<double>());
        edges[family] += r["edge_fraction"].get<double>();
    }
    auto summary = [](std::vector<double> v) {
        std::sort(v.begin(), v.end());
        double sum = 0;
        for (double x : v) sum += x;
        return json{{"min", v.front()},
                    {"median", v[v.size() / 2]},
                    {"mean", sum / double(v.size())},
                    {"max", v.back()}};
    };
    json out;
    std::vector<double> all;
    std::map<std::string, int> splits;
    for (const auto& [family, bySplit] : counts) {
        int total = 0;
        for (const auto& [split, n] : bySplit) total += n, splits[split] += n;
        out["families"][family] = {{"items", total},
                                   {"splits", bySplit},
                                   {"edge_fraction", edges[family] / total},
                                   {"aliased_psnr", summary(psnr[family])}};
        if (motion.count(family)) out["families"][family]["motion"] = motion[family].toJson();
        if (samplers.count(family)) out["families"][family]["samplers"] = samplers[family];
        all.insert(all.end(), psnr[family].begin(), psnr[family].end());
    }
    out["items"] = records.size();
    out["splits"] = splits;
    out["aliased_psnr"] = summary(all);
    out["flat_items"] = flat;
    out["samplers"] = allSamplers;
    if (allMotion.sequences > 0) out["motion"] = allMotion.toJson();
    return out;
}

}  // namespace dejag::data
