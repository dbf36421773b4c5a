#include "base/communicator.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <optional>

#include "base/error.h"

namespace dejag {
namespace {

std::unique_ptr<Communicator>& installed() {
    static std::unique_ptr<Communicator> instance = std::make_unique<Communicator>();
    return instance;
}

}  // namespace

void Communicator::abort(const std::string& message, int code) {
    if (!message.empty()) std::fprintf(stderr, "%s\n", message.c_str());
    std::fflush(nullptr);
    std::_Exit(code);
}

std::string Communicator::rankLabel() const {
    return size() > 1 ? " (rank " + std::to_string(rank()) + " of " + std::to_string(size()) + ")" : "";
}

Communicator& communicator() {
    return *installed();
}

void setCommunicator(std::unique_ptr<Communicator> communicator) {
    installed() = std::move(communicator);
}

void sumInOrder(const float* mine, int64_t perRank, int64_t vectors, int64_t count, float* sum,
                std::vector<float>& scratch) {
    Communicator& comm = communicator();
    const int64_t N = comm.size();
    if (vectors < 1 || perRank < 1 || perRank * N < vectors) throw Error("sumInOrder: bad shares");
    // Slice d of every vector goes to rank d: slices of `slice` floats, the last ones padded.
    const int64_t slice = (count + N - 1) / N;
    const size_t block = size_t(perRank * slice);  // what one rank sends another
    // send and received: a block for each rank; then this rank's summed slice, and every rank's.
    scratch.resize(2 * block * size_t(N) + size_t(slice) + size_t(slice * N));
    float* send = scratch.data();
    float* received = send + block * size_t(N);
    float* mySum = received + block * size_t(N);
    float* gathered = mySum + slice;
    for (int64_t d = 0; d < N; ++d)
        for (int64_t j = 0; j < perRank; ++j) {
            float* to = send + size_t(d) * block + size_t(j * slice);
            const int64_t from = d * slice, n = std::max<int64_t>(0, std::min(slice, count - from));
            std::copy_n(mine + j * count + from, n, to);
            std::fill(to + n, to + slice, 0.0f);
        }
    comm.allToAll(send, int64_t(block), received);
    // From rank s: its vectors s k + j, so received holds the vectors in order.
    std::copy_n(received, slice, mySum);
    for (int64_t v = 1; v < vectors; ++v) {
        const float* other = received + size_t(v * slice);
        for (int64_t i = 0; i < slice; ++i) mySum[i] += other[i];
    }
    comm.allGather(mySum, slice, gathered);
    std::copy_n(gathered, count, sum);
}

void together(const std::function<void()>& body) {
    Communicator& comm = communicator();
    if (comm.size() == 1) return body();
    std::optional<Error> mine;
    try {
        body();
    } catch (const Error& e) {
        mine = e;
    }
    const double failed = mine ? 1.0 : 0.0;
    std::vector<double> all(size_t(comm.size()));
    comm.allGather(&failed, 1, all.data());
    const auto first = std::find(all.begin(), all.end(), 1.0);
    if (first == all.end()) return;
    if (mine && first - all.begin() == comm.rank()) throw *mine;
    throw ReportedElsewhere{2};
}

}  // namespace dejag
