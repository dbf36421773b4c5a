// dejag/base: files that are either complete or absent.
//
// Every output dejag writes goes to a temporary name in the destination folder and is renamed over the
// destination only once fully written and flushed to the disk, so an interrupted run or a full disk never
// leaves a half-written file behind and never destroys the previous version. Each step (open, every
// write, fsync, close, rename) is checked; a failure is a dejag::Error naming the file and the reason
// ("cannot write 'out.png': No space left on device").
//
// Temporary files are named ".STEM.tmp-PID-N.EXT". While one exists it is registered, and the handlers
// installed by installTemporaryFileCleanup() remove every registered one when the process is ended by
// SIGINT, SIGTERM or SIGHUP (SIGKILL cannot be caught: the next write into the same folder removes what a
// dead process left, and folder listings skip such names).
#pragma once

#include <string>
#include <string_view>

namespace dejag {

// A file being written under a temporary name next to `path`. write() appends; commit() fsyncs, closes and
// renames it over `path`. Destroyed uncommitted (an exception, an early return), it removes itself.
class AtomicFile {
  public:
    explicit AtomicFile(const std::string& path);
    ~AtomicFile();
    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    void write(const void* data, size_t bytes);
    void write(std::string_view text) { write(text.data(), text.size()); }
    void commit();
    const std::string& temporaryPath() const { return temporary_; }

  private:
    [[noreturn]] void fail(int error);  // removes the temporary file, throws naming the reason
    void discard();
    std::string path_, temporary_;
    int fd_ = -1;
    int slot_ = -1;
    bool committed_ = false;
};

// Writes `bytes` to `path` through an AtomicFile.
void writeBytesAtomically(const std::string& path, std::string_view bytes);
void writeTextFileAtomically(const std::string& path, const std::string& text);

// True for a name dejag gives its temporary files (".frame.tmp-123-4.exr"): folder listings skip them.
bool isTemporaryFileName(const std::string& fileName);

// Removes from `folder` the temporary files of processes that no longer run (killed by SIGKILL, or by a
// power cut). Called by every write, once per folder and process; safe to call any time.
void removeStaleTemporaryFiles(const std::string& folder);

// SIGINT, SIGTERM and SIGHUP remove the registered temporary files, then end the process as the signal
// would have (so the exit status still says which signal). SIGXFSZ is ignored, so that a file-size limit
// surfaces as a write error (EFBIG) like a full disk. Idempotent.
void installTemporaryFileCleanup();

// An advisory lock on a folder (flock on FOLDER/.dejag.lock, which the kernel releases when the process
// dies, however it dies): one process at a time writes a run or a dataset. A second is refused with one
// line naming the folder. The lock file stays, empty (so a folder's contents do not depend on who wrote it).
class FolderLock {
  public:
    static constexpr const char* kFileName = ".dejag.lock";
    // `what` names the work for the message: "a training run", "a dataset generation".
    FolderLock(const std::string& folder, const std::string& what);
    ~FolderLock();
    FolderLock(const FolderLock&) = delete;
    FolderLock& operator=(const FolderLock&) = delete;

  private:
    int fd_ = -1;
};

// Throws dejag::Error naming `path` if it does not exist or is not a readable regular file.
void requireReadableFile(const std::string& path);

// "No space left on device" for errno ENOSPC: the reason a user sees after "cannot write 'X': ".
std::string systemErrorText(int error);

}  // namespace dejag
