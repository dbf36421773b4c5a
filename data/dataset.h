// dejag/data: datasets of aliased frames and their supersampled truth, rendered from scene families.
//
// A dataset folder holds dataset.json (the arguments that define it), manifest.jsonl (one record per
// complete item, sorted by index once generation finishes) and items/FAMILY/ID_input.exr (lit colour +
// albedo, depth, motion, IDs of the aliased frame: unjittered, one sample per pixel) and ID_truth.exr
// (the accumulated truth of the same pose); or, for a sequence dataset, items/FAMILY/ID/ with the
// jittered frames of one camera move and their truths. Items are independent: item i's scene, camera, light,
// colours and time come from hash(seed, i) and its family from i, so a dataset renders the same on any
// number of workers and in any order.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace dejag::data {

struct FamilyInfo {
    std::string name;
    std::vector<std::string> scenes;  // render scene names drawn from
    std::string description;
};
// Every family (from the renderer's scene catalogue), in a stable order.
const std::vector<FamilyInfo>& datasetFamilies();
// Default held-out test families: scenes a network trained on the others has never seen.
const std::vector<std::string>& defaultTestFamilies();

struct DatasetSpec {
    std::vector<std::string> families;      // drawn round-robin by item index
    std::vector<std::string> testFamilies;  // held out entirely (a subset of families)
    int count = 0;
    int width = 256, height = 256;
    int truthSamples = 128;
    bool adaptive = true;
    uint64_t seed = 1;
    double validationFraction = 0.1;  // of the non-test items, chosen by item seed
    // Sequences: with sequenceLength K >= 2 an item is K consecutive frames of a moving camera (and
    // moving objects), each jittered by a Halton(2,3) point of this spread in pixels and with the truth of
    // its own pose (docs/data.md, "Sequences"). 1: single unjittered frames.
    int sequenceLength = 1;
    double jitterSpread = 1.0;
    // The share of items framed as close-ups (docs/data.md, "Close-ups"): the view's field of view
    // narrowed 1.5-4.5x (log-uniform) and aimed at a random point of it, as a 256-pixel crop of a
    // full-HD frame sees the scene, with its long edges. 0 (the default, and what older datasets hold).
    double closeUps = 0.0;
    // The texture samplers drawn (uniformly, per item) for textured scenes, by render name (docs/data.md,
    // "Samplers"). The default is what older datasets hold; a dataset with it writes no "samplers" key.
    std::vector<std::string> samplers = defaultSamplers();
    static std::vector<std::string> defaultSamplers() { return {"point", "bilinear", "trilinear"}; }
    bool sequences() const { return sequenceLength > 1; }

    // Throws dejag::Error for an unknown family, count < 1, a bad size or sample count.
    void validate() const;
    nlohmann::json toJson() const;
    static DatasetSpec fromJson(const nlohmann::json& j);
};

enum class Split { Train, Validation, Test };
const char* splitName(Split split);

// What item `index` of a dataset is, before it is rendered.
struct ItemPlan {
    int index = 0;
    std::string id;  // "000042"
    std::string family, scene;
    uint64_t seed = 0;
    Split split = Split::Train;
    double time = 0;  // scene time (animated scenes); a sequence's first frame
    std::string inputFile() const { return "items/" + family + "/" + id + "_input.exr"; }
    std::string truthFile() const { return "items/" + family + "/" + id + "_truth.exr"; }

    // Sequences only: how the camera moves over the K frames, in pixels a frame at its target's distance.
    struct Move {
        std::string kind = "still";  // still | pan | orbit | dolly
        double speed = 0;            // pixels per frame
        double direction = 0;        // pan: angle in the image plane (0 = right, pi/2 = up); orbit and
                                     // dolly: its cosine's sign picks the way (around / in or out)
        double timeStep = 1;         // scene time per frame: 0 freezes the scene's own animation
        int cut = -1;                // the frame that starts a second shot (another view), or -1
        int jitterStart = 0;         // the Halton point of frame 0 (frame k takes point jitterStart + k)
    } move;
    // A sequence's folder and files: frame_NNNN.exr (the jittered frame and its buffers),
    // truth_NNNN.exr, render.json (jitter, cuts, cameras; what dejag filter reads beside a sequence).
    std::string sequenceFolder() const { return "items/" + family + "/" + id; }
    std::string sequenceFile(const char* stem, int frame) const;
};
ItemPlan planItem(const DatasetSpec& spec, int index);

// Renders item `plan` into `folder` (files written atomically) and returns its manifest record.
// Needs a current OpenGL context in this process (render::createOsMesaContext()).
class ItemRenderer {
  public:
    ItemRenderer();
    ~ItemRenderer();
    ItemRenderer(const ItemRenderer&) = delete;
    ItemRenderer& operator=(const ItemRenderer&) = delete;
    nlohmann::json render(const DatasetSpec& spec, const ItemPlan& plan, const std::string& folder);

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

// FNV-1a 64-bit of a file's bytes, as 16 hex digits. Throws dejag::Error if unreadable.
std::string fileChecksum(const std::string& path);

// manifest.jsonl: records in file order; a truncated last line (an interrupted append) is ignored.
std::vector<nlohmann::json> readManifest(const std::string& folder);

struct GenerateOptions {
    int workers = 1;     // processes, each with its own OpenGL context
    bool quiet = false;  // no progress bar
    // The program each worker process runs (exec'd after the fork), followed by `--folder F --items
    // i,j,k --result-fd N`; it must call runDatasetWorker. The `dejag` binary passes its own
    // `data worker`. Empty: the forked child renders itself — only safe in a process with one thread,
    // since a lock another thread held at the fork stays locked in the child (seen as a hang under
    // ASan, whose allocator lock a pool thread can hold).
    std::vector<std::string> workerCommand;
    // Testing: the process of this rank (dejag-mpi) kills itself with SIGKILL once it has recorded this
    // many items (-1: never).
    int killRank = -1, killAfterItems = -1;
};
struct GenerateResult {
    int rendered = 0, skipped = 0;
    double seconds = 0;
};
// Renders every missing item of the dataset in `folder` (creating it), resuming an interrupted run:
// complete items (in the manifest, files present) are skipped, partial ones redone. Throws
// dejag::Error if the folder holds a different dataset.
GenerateResult generateDataset(const DatasetSpec& spec, const std::string& folder,
                               const GenerateOptions& options);
// A worker of generateDataset (its workerCommand): renders the items of the dataset in `folder` and
// reports each on file descriptor `resultFd`, then exits the process.
[[noreturn]] void runDatasetWorker(const std::string& folder, const std::vector<int>& items, int resultFd);

struct VerifyReport {
    int items = 0;
    std::vector<std::string> problems;  // one line each: missing, wrong size, checksum, extra file
    bool ok() const { return problems.empty(); }
};
VerifyReport verifyDataset(const std::string& folder);

// An item whose 1-sample frame is this close to its truth (PSNR in dB) has nothing to anti-alias: one
// flat surface filling the view, say. Such an item scores near-perfectly for every method.
inline constexpr double kFlatItemPsnr = 80.0;

// Items per family and split, fraction of edge pixels, aliased-vs-truth PSNR distribution, and the flat
// items ("flat_items": id, family, split, aliased_psnr of each). For sequences also "motion" per family
// and overall: speeds, moving and disoccluded pixels, camera moves, cuts.
nlohmann::json datasetStats(const std::string& folder);

}  // namespace dejag::data
