// dejag/base: the processes of one job, for the stages that can share work between them (`dejag-mpi`:
// data-parallel training, sharded dataset generation; docs/mpi.md).
//
// A plain `dejag` is one process and links no MPI: communicator() is then rank 0 of 1 and every
// collective returns at once. `dejag-mpi` installs an MPI communicator before it parses the command line.
// The collectives are blocking, and every rank must call them in the same order with the same sizes.
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace dejag {

class Communicator {
  public:
    virtual ~Communicator() = default;
    virtual int rank() const { return 0; }
    virtual int size() const { return 1; }
    // Every rank's `count` floats (`count` equal on every rank), in rank order: all[r * count + i].
    virtual void allGather(const float* mine, int64_t count, float* all) {
        std::copy(mine, mine + count, all);
    }
    virtual void allGather(const double* mine, int64_t count, double* all) {
        std::copy(mine, mine + count, all);
    }
    // Every rank sends `count` floats to each rank (to rank d: mine[d * count ...]) and receives each
    // rank's (from rank s: all[s * count ...]).
    virtual void allToAll(const float* mine, int64_t count, float* all) {
        std::copy(mine, mine + count, all);
    }
    // The sum over the ranks, in place, in the order MPI chooses (which may differ between runs and rank
    // counts): what `dejag bench collective` compares the gather with; training sums in a fixed order.
    virtual void allReduceSum(float* /*data*/, int64_t /*count*/) {}
    // Root's bytes, to every rank (their `bytes` resized to it).
    virtual void broadcast(std::string& bytes, int /*root*/) { (void)bytes; }
    virtual void barrier() {}
    // Ends every process of the job at once (after `message`, if not empty, on this rank's stderr).
    [[noreturn]] virtual void abort(const std::string& message, int code);
    // "" for one process, else " (rank R of N)": for messages that must say which process speaks.
    std::string rankLabel() const;
};

// The sum of `vectors` vectors of `count` floats that the job's ranks hold between them, added in vector
// order, v0 + v1 + ... (each element's additions in that order, whatever the number of ranks), on every
// rank. Rank r holds vectors r k .. r k + k - 1 (k = perRank; vectors past the last are ignored, their
// slots anything) in `mine` (k count floats, vector after vector); `sum` receives count floats. A
// reduce-scatter by all-to-all (each rank adds up its own slice of every vector, in order), then a gather
// of the slices: about 2 count floats through each rank, as an all-reduce, but in a fixed order. One
// process: the sum in place of the gather. `scratch` is reused between calls.
void sumInOrder(const float* mine, int64_t perRank, int64_t vectors, int64_t count, float* sum,
                std::vector<float>& scratch);

// The job's communicator (one process unless setCommunicator was called).
Communicator& communicator();
void setCommunicator(std::unique_ptr<Communicator> communicator);

// An error another rank reported and printed: this rank exits with its code and prints nothing more.
struct ReportedElsewhere {
    int code = 2;
};

// Runs `body` on every rank, then agrees on the outcome: where it threw dejag::Error on any rank, it
// throws on every rank, the lowest failing rank its own error (to be printed) and the others
// ReportedElsewhere, so a setup error that every rank meets is one line, and no rank is left waiting in
// a later collective. One process: `body` alone.
void together(const std::function<void()>& body);

}  // namespace dejag
