// The MPI communicator of `dejag-mpi` (base/communicator.h): MPI_COMM_WORLD, its collectives on the main
// thread only (MPI_THREAD_FUNNELED; dejag's thread pool never calls MPI).
#include <mpi.h>

#include <climits>
#include <cstdio>
#include <string>

#include "app/mpi.h"
#include "base/communicator.h"
#include "base/error.h"

namespace dejag::cli {
namespace {

class MpiCommunicator final : public Communicator {
  public:
    MpiCommunicator() {
        MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
        MPI_Comm_size(MPI_COMM_WORLD, &size_);
    }
    int rank() const override { return rank_; }
    int size() const override { return size_; }
    void allGather(const float* mine, int64_t count, float* all) override {
        MPI_Allgather(mine, checkedCount(count), MPI_FLOAT, all, checkedCount(count), MPI_FLOAT,
                      MPI_COMM_WORLD);
    }
    void allGather(const double* mine, int64_t count, double* all) override {
        MPI_Allgather(mine, checkedCount(count), MPI_DOUBLE, all, checkedCount(count), MPI_DOUBLE,
                      MPI_COMM_WORLD);
    }
    void allToAll(const float* mine, int64_t count, float* all) override {
        MPI_Alltoall(mine, checkedCount(count), MPI_FLOAT, all, checkedCount(count), MPI_FLOAT,
                     MPI_COMM_WORLD);
    }
    void allReduceSum(float* data, int64_t count) override {
        MPI_Allreduce(MPI_IN_PLACE, data, checkedCount(count), MPI_FLOAT, MPI_SUM, MPI_COMM_WORLD);
    }
    void broadcast(std::string& bytes, int root) override {
        long long size = static_cast<long long>(bytes.size());
        MPI_Bcast(&size, 1, MPI_LONG_LONG, root, MPI_COMM_WORLD);
        bytes.resize(size_t(size));
        MPI_Bcast(bytes.data(), checkedCount(size), MPI_CHAR, root, MPI_COMM_WORLD);
    }
    void barrier() override { MPI_Barrier(MPI_COMM_WORLD); }
    [[noreturn]] void abort(const std::string& message, int code) override {
        if (!message.empty()) std::fprintf(stderr, "%s\n", message.c_str());
        std::fflush(nullptr);
        MPI_Abort(MPI_COMM_WORLD, code);
        std::_Exit(code);
    }

  private:
    static int checkedCount(int64_t count) {
        if (count < 0 || count > INT_MAX)
            throw Error("an MPI message of " + std::to_string(count) + " values");
        return int(count);
    }
    int rank_ = 0, size_ = 1;
};

}  // namespace

MpiSession::MpiSession(int& argc, char**& argv) {
    // A dataset worker is a child of one rank, started by it (`data worker`): not a process of the job.
    if (argc >= 3 && std::string(argv[1]) == "data" && std::string(argv[2]) == "worker") return;
    int provided = 0;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    setCommunicator(std::make_unique<MpiCommunicator>());
    // Rank 0 speaks for the job (progress, tables, JSON); the others keep stderr for their own errors.
    if (communicator().rank() > 0 && !std::freopen("/dev/null", "w", stdout))
        std::fprintf(stderr, "dejag-mpi: cannot silence rank %d's output\n", communicator().rank());
}

int MpiSession::finish(int code) {
    int initialised = 0;
    MPI_Initialized(&initialised);
    if (!initialised) return code;
    if (code != 0 && communicator().size() > 1) {
        // The other ranks may wait in a collective this rank will never reach: end the job.
        std::fflush(nullptr);
        MPI_Abort(MPI_COMM_WORLD, code);
    }
    MPI_Finalize();
    return code;
}

}  // namespace dejag::cli
