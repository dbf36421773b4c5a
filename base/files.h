// dejag/base: files that are either complete or absent.
//
// Every output dejag writes goes to a temporary name in the destination folder and is renamed over the
// destination only once fully written, so an interrupted run never leaves a half-written file behind and
// never destroys the previous version.
#pragma once

#include <functional>
#include <string>

namespace dejag {

// Calls write(temporaryPath), then renames the temporary file to `path`. If write throws, the temporary
// file is removed and the exception propagates; `path` is untouched. The temporary name keeps the
// extension of `path` so format-by-extension writers still work.
void writeFileAtomically(const std::string& path,
                         const std::function<void(const std::string& temporaryPath)>& write);

void writeTextFileAtomically(const std::string& path, const std::string& text);

// Throws dejag::Error naming `path` if it does not exist or is not a readable regular file.
void requireReadableFile(const std::string& path);

}  // namespace dejag
