// Fuzz target: the dataset manifest (manifest.jsonl, one JSON record per line) through its reader and
// the two commands that interpret every record, `dejag data verify` and `dejag data stats`.
#include <cstdint>

#include "base/error.h"
#include "data/dataset.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static const bool described = [] {  // a dataset.json, so verify reaches the records
        dejag::data::DatasetSpec spec;
        for (const dejag::data::FamilyInfo& family : dejag::data::datasetFamilies())
            spec.families.push_back(family.name);
        spec.testFamilies = dejag::data::defaultTestFamilies();
        spec.count = 4;
        const std::string text = spec.toJson().dump();
        dejag::fuzz::writeScratchFile("dataset.json", reinterpret_cast<const uint8_t*>(text.data()),
                                      text.size());
        return true;
    }();
    (void)described;
    dejag::fuzz::writeScratchFile("manifest.jsonl", data, size);
    const std::string folder = dejag::fuzz::scratchFolder().string();
    try {
        (void)dejag::data::readManifest(folder);
    } catch (const dejag::Error&) {
    }
    try {
        (void)dejag::data::verifyDataset(folder);
    } catch (const dejag::Error&) {
    }
    try {
        (void)dejag::data::datasetStats(folder);
    } catch (const dejag::Error&) {
    }
    return 0;
}
