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
