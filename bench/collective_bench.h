// dejag/bench: what sharing training between processes costs (`mpirun -np N dejag-mpi bench collective`):
// the ordered sum of the micro-batches' gradients that makes data-parallel training exact (sumInOrder,
// base/communicator.h, docs/mpi.md), timed at several sizes beside MPI's own all-reduce of the same
// values; a fit of latency and bandwidth to each, and from it a model of the scaling efficiency at more
// ranks for a network's gradient size and a step time measured on one process.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <vector>

namespace dejag::bench {

struct CollectiveBenchOptions {
    std::vector<int64_t> floats = {1024, 8192, 65536, 262144, 1048576};  // values each rank sends
    int repeat = 20;                                                     // timed calls after 3 warm-ups
    int64_t parameters = 0;  // the model's gradient size in floats (0: no model)
    double stepSeconds = 0;  // one process's time for a step of the global batch (0: no model)
    std::vector<int> ranks = {2, 4, 8, 16, 32, 64};
    // The model with a given network's latency and bandwidth per message instead of the measured ones
    // (0: measured).
    double networkLatencyUs = 0, networkGbPerS = 0;
};

// {"ranks", "sizes": [{floats, ordered_ms, allreduce_ms} medians], "fit": {ordered/allreduce: latency_us,
// gb_per_s}, "model": [{ranks, compute_ms, ordered_ms, allreduce_ms, efficiency_ordered,
// efficiency_allreduce}]}.
// Every rank must call it; one process: the sizes time nothing and the model uses no measurement.
nlohmann::json benchCollective(const CollectiveBenchOptions& options);

}  // namespace dejag::bench
