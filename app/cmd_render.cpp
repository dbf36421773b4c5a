// dejag render: draws a procedural scene headlessly (OSMesa) into multi-channel EXRs with PNG previews,
// optional accumulated ground truth, and a JSON sidecar.
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

#include "app/cli.h"
#include "app/commands.h"
#include "base/error.h"
#include "base/files.h"
#include "base/progress.h"
#include "base/timer.h"
#include "data/frame_image.h"
#include "data/image.h"
#include "render/gl.h"
#include "render/halton.h"
#include "render/renderer.h"
#include "render/scene.h"

namespace dejag::cli {
namespace {

struct RenderArguments {
    std::string scene, size = "800x800", out, jitter = "none", buffers = "color", camera = "regular";
    std::string sampler = "trilinear", texture = "checker", filter = "box";
    int frames = 1, truth = 0, start = 0, msaa = 1;
    uint64_t seed = 1;
    double spread = 1.7, tolerance = 1e-3, pixelTolerance = 2e-3;
    int tile = 8;
    render::FourierOptions fourier;
    std::string bump = "procedural";
    int bumpLobes = 4;
    bool bumpLobesGiven = false, fourierGiven = false;
    bool adaptive = false, list = false, json = false, quiet = false, force = false;
    RuntimeOptions runtime;
};

std::string framePath(const std::string& folder, const char* stem, int index, const char* extension) {
    char name[64];
    std::snprintf(name, sizeof name, "%s_%04d.%s", stem, index, extension);
    return (std::filesystem::path(folder) / name).string();
}

// A render never mixes with another in one folder: an earlier render (its render.json) or a file this one
// would write is refused unless --force; then the earlier render's files (those its render.json lists,
// and their previews) are removed first, so no frame of it stays beside the new ones.
void claimOutputFolder(const RenderArguments& args) {
    namespace fs = std::filesystem;
    const fs::path folder(args.out), sidecar = folder / "render.json";
    std::error_code error;
    std::vector<fs::path> earlier;
    std::string what;
    if (fs::exists(sidecar, error)) {
        std::ifstream in(sidecar);
        const nlohmann::json old = nlohmann::json::parse(in, nullptr, false);
        what = "a render";
        if (old.is_object() && old.contains("scene") && old["scene"].is_string()) {
            what += " of " + old["scene"].get<std::string>();
            if (old.contains("frames") && old["frames"].is_array()) {
                what += ", " + std::to_string(old["frames"].size()) + " frame(s)";
                for (const nlohmann::json& frame : old["frames"])
                    for (const nlohmann::json* entry :
                         {&frame, frame.contains("truth") ? &frame["truth"] : nullptr})
                        if (entry && entry->is_object() && entry->contains("file") &&
                            (*entry)["file"].is_string()) {
                            const fs::path file =
                                folder / fs::path((*entry)["file"].get<std::string>()).filename();
                            earlier.push_back(file);
                            earlier.push_back(fs::path(file).replace_extension(".png"));
                        }
            }
        }
        what += " (render.json)";
        earlier.push_back(sidecar);
    } else {
        for (int index = args.start; index < args.start + args.frames && what.empty(); ++index)
            for (const char* kind : {"frame", "truth"})
                for (const char* extension : {"exr", "png"})
                    if (const std::string path = framePath(args.out, kind, index, extension);
                        what.empty() && fs::exists(path, error))
                        what = "'" + fs::path(path).filename().string() + "'";
    }
    if (what.empty()) return;
    if (!args.force)
        throw Error("'" + args.out + "' already holds " + what +
                    "; choose another --out, or add --force to replace it");
    for (const fs::path& file : earlier) fs::remove(file, error);
}

// An sRGB 8-bit preview of the R, G, B channels.
void writePreview(const std::string& path, const Image& image) {
    Image preview(image.width, image.height, {"R", "G", "B"}, PixelType::UInt8);
    const int r = image.findChannel("R");
    for (size_t p = 0; p < image.pixelCount(); ++p)
        for (int c = 0; c < 3; ++c) {
            const float v = image.pixels[p * size_t(image.channels()) + size_t(r + c)];
            preview.pixels[p * 3 + size_t(c)] = std::clamp(linearToSrgb(std::max(v, 0.0f)), 0.0f, 1.0f);
        }
    writeImage(path, preview);
}

nlohmann::json vec(const render::Vec3& v) {
    return {v.x, v.y, v.z};
}

void runRender(const RenderArguments& args) {
    applyRuntimeOptions(args.runtime);
    if (args.list) {
        for (const render::SceneInfo& s : render::sceneCatalogue())
            std::printf("%-22s %-13s %s\n", s.name.c_str(), s.family.c_str(), s.description.c_str());
        return;
    }
    if (args.scene.empty()) throw Error("--scene is required (see --list)");
    if (args.out.empty()) throw Error("--out is required");
    if (args.frames < 1) throw Error("--frames must be at least 1, not " + std::to_string(args.frames));
    if (args.start < 0 || args.start > std::numeric_limits<int>::max() - (args.frames - 1))
        throw Error("--start " + std::to_string(args.start) + " with --frames " +
                    std::to_string(args.frames) + ": frame numbers run from 0 to " +
                    std::to_string(std::numeric_limits<int>::max()));
    if (args.truth < 0 || args.truth > 1 << 20)
        throw Error("--truth must be 0 (none) or a sample count up to 1048576");
    if (!(args.spread >= 0 && args.spread <= 64))
        throw Error("--jitter-spread must be from 0 to 64 pixels, not " + std::to_string(args.spread));
    if (!(args.tolerance > 0) || !(args.pixelTolerance > 0))
        throw Error("--tolerance and --pixel-tolerance must be above 0");
    if (args.jitter != "none" && args.jitter != "halton16")
        throw Error("--jitter must be none or halton16, not '" + args.jitter + "'");
    if (args.camera != "regular" && args.camera != "tilted")
        throw Error("--camera must be regular or tilted, not '" + args.camera + "'");
    if (args.filter != "box" && args.filter != "gaussian")
        throw Error("--truth-filter must be box or gaussian, not '" + args.filter + "'");
    const Size size = parseSize(args.size, "--size");
    const render::BufferSet buffers = render::BufferSet::parse(args.buffers);
    render::SceneOptions sceneOptions;
    sceneOptions.seed = args.seed;
    sceneOptions.tiltedCamera = args.camera == "tilted";
    sceneOptions.sampler = render::parseSampler(args.sampler);
    sceneOptions.texture = args.texture;
    sceneOptions.fourier = args.fourier;
    sceneOptions.bump = render::parseBump(args.bump);
    sceneOptions.bumpLobes = args.bumpLobes;
    const render::Scene scene = render::buildScene(args.scene, sceneOptions);
    if (sceneOptions.bump != render::Bump::Procedural && scene.normalMaps.empty())
        throw Error("--bump " + args.bump + ": scene '" + args.scene +
                    "' has no normal map (normal-map has)");
    if (args.bumpLobesGiven && sceneOptions.bump != render::Bump::Super)
        throw Error("--bump-lobes is for --bump super");
    if (args.fourierGiven && sceneOptions.sampler != render::Sampler::Fourier)
        throw Error("the --fourier-* options are for --sampler fourier");

    claimOutputFolder(args);
    std::error_code error;
    std::filesystem::create_directories(args.out, error);
    if (error || !std::filesystem::is_directory(args.out) || access(args.out.c_str(), W_OK) != 0)
        throw Error("cannot write to the output folder '" + args.out + "'");

    const auto context = render::createOsMesaContext();
    render::Renderer renderer(*context, scene, size.width, size.height);
    render::TruthOptions truthOptions;
    truthOptions.samples = args.truth;
    truthOptions.adaptive = args.adaptive;
    truthOptions.tolerance = args.tolerance;
    truthOptions.pixelTolerance = args.pixelTolerance;
    truthOptions.tileSize = args.tile;
    if (args.tile < 4 || args.tile > 256) throw Error("--truth-tile must be 4..256 pixels");
    truthOptions.filter = args.filter == "box" ? render::PixelFilter::Box : render::PixelFilter::Gaussian;

    nlohmann::json sidecar;
    sidecar["scene"] = args.scene;
    sidecar["size"] = {size.width, size.height};
    sidecar["seed"] = args.seed;
    sidecar["camera"] = args.camera;
    sidecar["sampler"] = args.sampler;
    if (!scene.normalMaps.empty()) {
        sidecar["bump"] = args.bump;
        if (sceneOptions.bump == render::Bump::Super) sidecar["bump_lobes"] = args.bumpLobes;
    }
    if (sceneOptions.sampler == render::Sampler::Fourier)
        sidecar["fourier"] = {{"frequencies", args.fourier.frequencies},
                              {"cutoff", args.fourier.cutoff},
                              {"sigma", args.fourier.sigma},
                              {"min_captured", args.fourier.minCaptured},
                              {"probes", args.fourier.probes}};
    if (args.scene == "planes") sidecar["texture"] = args.texture;
    sidecar["anisotropy_supported"] = renderer.anisotropySupported();
    sidecar["jitter"] = {{"mode", args.jitter},
                         {"spread", args.jitter == "none" ? 0.0 : args.spread},
                         {"sequence", "Halton(2,3), base-3 digits 1<->2 scrambled"}};
    sidecar["buffers"] = buffers.describe();
    sidecar["msaa"] = args.msaa;
    sidecar["channels"] = buffers.channelNames();
    sidecar["renderer"] = context->description();
    sidecar["depth_far"] = scene.far;  // depth.Z of the background; TAA normalises depth by it
    sidecar["triangles"] = scene.triangleCount();
    sidecar["objects"] = scene.objects.size();
    if (args.truth > 0)
        sidecar["truth"] = {{"samples", args.truth},
                            {"adaptive", args.adaptive},
                            {"filter", args.filter},
                            {"tolerance", args.adaptive ? args.tolerance : 0.0}};
    nlohmann::json frames = nlohmann::json::array();

    Progress progress("render " + args.scene, args.frames, args.quiet || args.json);
    double renderMs = 0, truthMs = 0;
    int64_t tileSamples = 0, fullTileSamples = 0;
    for (int i = 0; i < args.frames; ++i) {
        const int index = args.start + i;
        const double time = index;
        render::FrameRequest request;
        request.time = time;
        request.previousTime = index > 0 ? time - 1 : time;
        request.buffers = buffers;
        request.msaa = args.msaa;
        if (args.jitter == "halton16") {
            request.jitter = render::jitterPixels(unsigned(index % 16), args.spread);
            request.previousJitter = render::jitterPixels(unsigned((index + 15) % 16), args.spread);
        }
        const Stopwatch clock;
        Image image = imageFromFrame(renderer.render(request));
        renderMs += clock.elapsedMs();
        writeImage(framePath(args.out, "frame", index, "exr"), image);
        if (buffers.colour) writePreview(framePath(args.out, "frame", index, "png"), image);
        const render::CameraPose pose = scene.cameraAt(time);
        nlohmann::json record = {{"index", index},
                                 {"time", time},
                                 {"file", framePath("", "frame", index, "exr")},
                                 {"jitter_pixels", {request.jitter.x, -request.jitter.y}},
                                 {"camera",
                                  {{"eye", vec(pose.eye)},
                                   {"target", vec(pose.target)},
                                   {"up", vec(pose.up)},
                                   {"fov_y_degrees", pose.fovY * 180.0 / render::kPi}}}};
        if (args.truth > 0) {
            render::TruthStats stats;
            Image truth = imageFromFrame(renderer.renderTruth(time, truthOptions, &stats));
            truthMs += stats.milliseconds;
            tileSamples += stats.tileSamples, fullTileSamples += stats.fullTileSamples;
            writeImage(framePath(args.out, "truth", index, "exr"), truth);
            writePreview(framePath(args.out, "truth", index, "png"), truth);
            record["truth"] = {{"file", framePath("", "truth", index, "exr")},
                               {"samples", stats.samples},
                               {"tile_samples", stats.tileSamples},
                               {"full_tile_samples", stats.fullTileSamples},
                               {"saving", stats.saving()},
                               {"rounds", stats.rounds},
                               {"ms", stats.milliseconds}};
        }
        frames.push_back(record);
        progress.advance(1);
    }
    sidecar["frames"] = frames;
    sidecar["ms_per_frame"] = renderMs / args.frames;
    if (args.truth > 0) {
        sidecar["truth_ms_per_frame"] = truthMs / args.frames;
        sidecar["truth_saving"] = tileSamples > 0 ? double(fullTileSamples) / double(tileSamples) : 1.0;
    }
    writeTextFileAtomically((std::filesystem::path(args.out) / "render.json").string(),
                            sidecar.dump(2) + "\n");
    if (args.json) {
        std::printf("%s\n", sidecar.dump().c_str());
    } else if (!args.quiet) {
        std::printf("%s: %d frame(s) %dx%d to %s, %.1f ms per frame (%s)\n", args.scene.c_str(), args.frames,
                    size.width, size.height, args.out.c_str(), renderMs / args.frames,
                    buffers.describe().c_str());
        if (args.truth > 0)
            std::printf("truth: %d samples%s, %.0f ms per frame, %.2fx fewer tile-samples than full\n",
                        args.truth, args.adaptive ? " (adaptive)" : "", truthMs / args.frames,
                        tileSamples > 0 ? double(fullTileSamples) / double(tileSamples) : 1.0);
    }
}

}  // namespace

void registerRenderCommand(CLI::App& app) {
    auto args = std::make_shared<RenderArguments>();
    CLI::App* command = app.add_subcommand("render",
                                           "draw a procedural scene headlessly (OSMesa): EXR buffers, "
                                           "PNG previews, accumulated ground truth");
    command->add_option("--scene", args->scene, "scene name (see --list)");
    command->add_flag("--list", args->list, "print the scenes and exit");
    command->add_option("--size", args->size, "frame size WIDTHxHEIGHT")->capture_default_str();
    command->add_option("--frames", args->frames, "number of frames (scene time 0, 1, 2, ...)")
        ->capture_default_str();
    command->add_option("--start", args->start, "first frame index")->capture_default_str();
    command->add_option("--out", args->out, "output folder (created if missing)");
    command->add_option("--seed", args->seed, "seed of random scenes and textures")->capture_default_str();
    command->add_option("--jitter", args->jitter, "none | halton16 (camera jitter per frame, for TAA)")
        ->capture_default_str();
    command->add_option("--jitter-spread", args->spread, "jitter spread in pixels (docs/taa.md: 1.7)")
        ->capture_default_str();
    command->add_option("--truth", args->truth, "also accumulate N Halton-jittered samples as ground truth")
        ->capture_default_str();
    command->add_flag("--adaptive", args->adaptive, "stop accumulating tiles whose estimate converged");
    command->add_option("--tolerance", args->tolerance, "adaptive: RMS change per sample doubling")
        ->capture_default_str();
    command
        ->add_option("--pixel-tolerance", args->pixelTolerance, "adaptive: largest standard error of a pixel")
        ->capture_default_str();
    command->add_option("--truth-tile", args->tile, "adaptive: the truth's tile size in pixels")
        ->capture_default_str();
    command->add_option("--truth-filter", args->filter, "the truth's pixel filter: box | gaussian")
        ->capture_default_str();
    command->add_option("--msaa", args->msaa, "multisample the colour: 1 (off), 2, 4, 8")
        ->capture_default_str();
    command->add_option("--buffers", args->buffers, "color,albedo,depth,motion,id,prevdepth")
        ->capture_default_str();
    command->add_option("--camera", args->camera, "regular | tilted")->capture_default_str();
    command
        ->add_option("--sampler", args->sampler,
                     "point | bilinear | trilinear | aniso16 | fourier (textured scenes)")
        ->capture_default_str();
    command
        ->add_option("--bump", args->bump,
                     "normal-map scene: procedural (per fragment, unfiltered) | standard (a normal map's MIP "
                     "chain, read with --sampler) | super (super bump mapping)")
        ->capture_default_str();
    command
        ->add_option("--bump-lobes", args->bumpLobes, "super bump mapping: lit normals a MIP texel, 1 to 4")
        ->check(CLI::Range(1, 4))
        ->capture_default_str();
    command
        ->add_option("--fourier-frequencies", args->fourier.frequencies,
                     "fourier sampler: sinusoids added back per pixel")
        ->check(CLI::Range(1, 1024))
        ->capture_default_str();
    command
        ->add_option("--fourier-cutoff", args->fourier.cutoff,
                     "fourier sampler: the MIP levels keep this fraction of their Nyquist limit")
        ->check(CLI::Range(0.01, 1.0))
        ->capture_default_str();
    command
        ->add_option("--fourier-sigma", args->fourier.sigma,
                     "fourier sampler: the Gaussian pixel filter's standard deviation in pixels")
        ->check(CLI::Range(0.0, 4.0))
        ->capture_default_str();
    command
        ->add_option("--fourier-min-captured", args->fourier.minCaptured,
                     "fourier sampler: a set holding less of its energy than this reads trilinearly")
        ->check(CLI::Range(0.0, 1.0))
        ->capture_default_str();
    command
        ->add_option("--fourier-probes", args->fourier.probes,
                     "fourier sampler: band reads along an anisotropic footprint's major axis (1: one "
                     "isotropic read, as the thesis does)")
        ->check(CLI::IsMember({1, 2, 4, 8, 16}))
        ->capture_default_str();
    command->add_option("--texture", args->texture, "planes: checker | bricks | stripes | text | noise")
        ->capture_default_str();
    command->add_flag("--json", args->json, "print the JSON sidecar on stdout");
    command->add_flag("--quiet", args->quiet, "no progress or summary");
    command->add_flag(
        "--force", args->force,
        "replace an earlier render in --out (its frames are removed first); without it, refused");
    addRuntimeOptions(command, args->runtime);
    command->footer(
        "Writes per frame frame_NNNN.exr (float; channels R G B, albedo.R/G/B, depth.Z, motion.X/Y, id.ID,\n"
        "prevdepth.Z as requested), frame_NNNN.png (sRGB preview), truth_NNNN.exr/.png with --truth, and\n"
        "render.json (camera, seed, jitter, sample counts). Channel meanings: docs/render.md.");
    command->callback([args, command] {
        args->bumpLobesGiven = command->count("--bump-lobes") > 0;
        args->fourierGiven = command->count("--fourier-frequencies") + command->count("--fourier-cutoff") +
                                 command->count("--fourier-sigma") +
                                 command->count("--fourier-min-captured") +
                                 command->count("--fourier-probes") >
                             0;
        runRender(*args);
    });
}

}  // namespace dejag::cli
