#include "base/files.h"

#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <climits>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <set>

#include "base/error.h"

namespace dejag {
namespace fs = std::filesystem;

namespace {

// ---- The registry of live temporary files, read by the signal handler ----------------------------------
// Fixed slots, so the handler touches no allocator and no lock: a slot is claimed (0 -> 1), its path
// copied, then published (2); the handler unlinks published paths only.
constexpr int kSlots = 256;
struct Slot {
    std::atomic<int> state{0};
    char path[PATH_MAX];
};
std::array<Slot, kSlots> slots;

int registerTemporary(const std::string& path) {
    if (path.size() >= PATH_MAX) return -1;
    for (int i = 0; i < kSlots; ++i) {
        int expected = 0;
        if (slots[size_t(i)].state.compare_exchange_strong(expected, 1)) {
            std::memcpy(slots[size_t(i)].path, path.c_str(), path.size() + 1);
            slots[size_t(i)].state.store(2);
            return i;
        }
    }
    return -1;  // more than 256 files at once: still written safely, only not removed by a signal
}

void unregisterTemporary(int slot) {
    if (slot >= 0) slots[size_t(slot)].state.store(0);
}

extern "C" void removeTemporariesAndDie(int signal) {
    for (Slot& slot : slots)
        if (slot.state.load() == 2) ::unlink(slot.path);
    ::signal(signal, SIG_DFL);
    ::raise(signal);
}

std::string temporaryNameFor(const fs::path& path) {
    static std::atomic<unsigned> counter{0};
    fs::path parent = path.parent_path();
    std::string name = "." + path.stem().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                       std::to_string(counter.fetch_add(1)) + path.extension().string();
    return (parent / name).string();
}

fs::path folderOf(const fs::path& target) {
    return target.parent_path().empty() ? fs::path(".") : target.parent_path();
}

void requireWritableTarget(const std::string& path) {
    const fs::path target(path), parent = folderOf(target);
    std::error_code ec;
    if (!fs::is_directory(parent, ec))
        throw Error("cannot write '" + path + "': folder '" + parent.string() + "' does not exist");
    if (fs::is_directory(target, ec)) throw Error("cannot write '" + path + "': it is a folder");
    removeStaleTemporaryFiles(parent.string());
}

// Makes a rename durable: the folder's entry is flushed too (best effort; some file systems refuse).
void syncFolder(const fs::path& folder) {
    const int fd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0) return;
    ::fsync(fd);
    ::close(fd);
}

}  // namespace

std::string systemErrorText(int error) {
    return std::strerror(error);
}

// ---- AtomicFile ----------------------------------------------------------------------------------------

AtomicFile::AtomicFile(const std::string& path) : path_(path) {
    requireWritableTarget(path);
    temporary_ = temporaryNameFor(fs::path(path));
    slot_ = registerTemporary(temporary_);
    fd_ = ::open(temporary_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd_ < 0) {
        const int error = errno;
        unregisterTemporary(slot_);
        slot_ = -1;
        throw Error("cannot write '" + path_ + "': " + systemErrorText(error));
    }
}

AtomicFile::~AtomicFile() {
    if (!committed_) discard();
}

void AtomicFile::discard() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    if (!temporary_.empty()) ::unlink(temporary_.c_str());
    unregisterTemporary(slot_);
    slot_ = -1;
}

void AtomicFile::fail(int error) {
    discard();
    throw Error("cannot write '" + path_ + "': " + systemErrorText(error));
}

void AtomicFile::write(const void* data, size_t bytes) {
    if (fd_ < 0) throw Error("cannot write '" + path_ + "': the file is already closed");
    const char* p = static_cast<const char*>(data);
    while (bytes > 0) {
        const ssize_t n = ::write(fd_, p, std::min<size_t>(bytes, size_t(1) << 30));
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) fail(n < 0 ? errno : EIO);
        p += n, bytes -= size_t(n);
    }
}

void AtomicFile::commit() {
    if (fd_ < 0) throw Error("cannot write '" + path_ + "': the file is already closed");
    // fsync reports what the page cache could not write back (a full thin-provisioned disk, NFS quota).
    if (::fsync(fd_) != 0 && errno != EINVAL) fail(errno);
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0 && errno != EINTR) fail(errno);
    if (::rename(temporary_.c_str(), path_.c_str()) != 0) fail(errno);
    committed_ = true;
    unregisterTemporary(slot_);
    slot_ = -1;
    syncFolder(folderOf(fs::path(path_)));
}

void writeBytesAtomically(const std::string& path, std::string_view bytes) {
    AtomicFile file(path);
    file.write(bytes);
    file.commit();
}

void writeTextFileAtomically(const std::string& path, const std::string& text) {
    writeBytesAtomically(path, text);
}

// ---- Temporary files of other processes ------------------------------------------------------------------

bool isTemporaryFileName(const std::string& name) {
    if (name.size() < 8 || name[0] != '.') return false;
    const size_t tag = name.rfind(".tmp-");
    if (tag == std::string::npos || tag == 0) return false;
    size_t i = tag + 5, digits = 0;
    for (; i < name.size() && std::isdigit(static_cast<unsigned char>(name[i])); ++i) ++digits;
    if (digits == 0 || i >= name.size() || name[i] != '-') return false;
    size_t counter = 0;
    for (++i; i < name.size() && std::isdigit(static_cast<unsigned char>(name[i])); ++i) ++counter;
    return counter > 0 && (i == name.size() || name[i] == '.');
}

void removeStaleTemporaryFiles(const std::string& folder) {
    static std::mutex mutex;
    static std::set<std::string> swept;
    std::error_code ec;
    const std::string key = fs::weakly_canonical(folder, ec).string();
    {
        std::lock_guard<std::mutex> lock(mutex);
        if (!swept.insert(key.empty() ? folder : key).second) return;
    }
    DIR* dir = ::opendir(folder.c_str());
    if (!dir) return;
    const pid_t self = ::getpid();
    while (const dirent* entry = ::readdir(dir)) {
        const std::string name = entry->d_name;
        if (!isTemporaryFileName(name)) continue;
        const size_t tag = name.rfind(".tmp-");
        const long pid = std::strtol(name.c_str() + tag + 5, nullptr, 10);
        if (pid <= 0 || pid > INT_MAX || pid_t(pid) == self) continue;
        // A process that still runs (or that we may not signal) keeps its file.
        if (::kill(pid_t(pid), 0) == 0 || errno != ESRCH) continue;
        ::unlinkat(::dirfd(dir), name.c_str(), 0);
    }
    ::closedir(dir);
}

void installTemporaryFileCleanup() {
    static std::once_flag once;
    std::call_once(once, [] {
        struct sigaction action {};
        action.sa_handler = removeTemporariesAndDie;
        sigemptyset(&action.sa_mask);
        action.sa_flags = SA_RESETHAND;
        for (int signal : {SIGINT, SIGTERM, SIGHUP}) {
            struct sigaction previous {};
            // A signal the parent told us to ignore (nohup, a shell's background job) stays ignored.
            if (::sigaction(signal, nullptr, &previous) == 0 && previous.sa_handler == SIG_IGN) continue;
            ::sigaction(signal, &action, nullptr);
        }
        ::signal(SIGXFSZ, SIG_IGN);
    });
}

// ---- FolderLock -----------------------------------------------------------------------------------------

FolderLock::FolderLock(const std::string& folder, const std::string& what) {
    const std::string path = (fs::path(folder) / kFileName).string();
    fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) throw Error("cannot lock '" + folder + "': " + systemErrorText(errno));
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
        const int error = errno;
        ::close(fd_);
        fd_ = -1;
        if (error != EWOULDBLOCK) throw Error("cannot lock '" + folder + "': " + systemErrorText(error));
        throw Error("'" + folder + "' is in use by " + what +
                    " of another dejag process; wait for it to end or choose another folder");
    }
}

FolderLock::~FolderLock() {
    if (fd_ >= 0) ::close(fd_);  // releases the lock
}

void requireReadableFile(const std::string& path) {
    std::error_code ec;
    fs::file_status status = fs::status(path, ec);
    if (!fs::exists(status)) throw Error("cannot read '" + path + "': no such file");
    if (fs::is_directory(status)) throw Error("cannot read '" + path + "': it is a folder, not a file");
    if (::access(path.c_str(), R_OK) != 0) throw Error("cannot read '" + path + "': " + std::strerror(errno));
}

}  // namespace dejag
