#include "base/thread_pool.h"

#include <pmmintrin.h>
#include <xmmintrin.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdlib>
#include <exception>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "base/error.h"

namespace dejag {
namespace {

thread_local bool t_insideParallelBody = false;

struct Job {
    const ParallelBody* body = nullptr;
    int64_t end = 0;
    int64_t grain = 1;
    std::atomic<int64_t> next{0};
    std::mutex errorMutex;
    std::exception_ptr error;

    void runChunks() {
        t_insideParallelBody = true;
        for (;;) {
            int64_t start = next.fetch_add(grain, std::memory_order_relaxed);
            if (start >= end) break;
            try {
                (*body)(start, std::min(start + grain, end));
            } catch (...) {
                std::lock_guard<std::mutex> lock(errorMutex);
                if (!error) error = std::current_exception();
                next.store(end, std::memory_order_relaxed);
            }
        }
        t_insideParallelBody = false;
    }
};

class ThreadPool {
  public:
    explicit ThreadPool(int threads) : threads_(threads) {
        for (int i = 1; i < threads; ++i) workers_.emplace_back([this] { workerLoop(); });
    }

    ~ThreadPool() {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stop_ = true;
        }
        wake_.notify_all();
        for (auto& worker : workers_) worker.join();
    }

    int threads() const { return threads_; }

    void parallelFor(int64_t begin, int64_t end, int64_t grain, const ParallelBody& body) {
        if (end <= begin) return;
        const int64_t count = end - begin;
        if (grain <= 0) grain = std::max<int64_t>(1, count / (int64_t(threads_) * 4));
        if (threads_ == 1 || count <= grain || t_insideParallelBody) {
            body(begin, end);
            return;
        }
        std::lock_guard<std::mutex> oneJobAtATime(runMutex_);
        Job job;
        job.body = &body;
        job.next.store(begin);
        job.end = end;
        job.grain = grain;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            job_ = &job;
            ++generation_;
            busyWorkers_ = int(workers_.size());
        }
        wake_.notify_all();
        job.runChunks();
        {
            std::unique_lock<std::mutex> lock(mutex_);
            done_.wait(lock, [&] { return busyWorkers_ == 0; });
            job_ = nullptr;
        }
        if (job.error) std::rethrow_exception(job.error);
    }

  private:
    void workerLoop() {
        flushDenormalsOnThisThread();
        uint64_t seenGeneration = 0;
        for (;;) {
            Job* job = nullptr;
            {
                std::unique_lock<std::mutex> lock(mutex_);
                wake_.wait(lock, [&] { return stop_ || generation_ != seenGeneration; });
                if (stop_) return;
                seenGeneration = generation_;
                job = job_;
            }
            job->runChunks();
            {
                std::lock_guard<std::mutex> lock(mutex_);
                if (--busyWorkers_ == 0) done_.notify_one();
            }
        }
    }

    const int threads_;
    std::vector<std::thread> workers_;
    std::mutex runMutex_;
    std::mutex mutex_;
    std::condition_variable wake_;
    std::condition_variable done_;
    Job* job_ = nullptr;
    uint64_t generation_ = 0;
    int busyWorkers_ = 0;
    bool stop_ = false;
};

int defaultThreadCount() {
    if (const char* env = std::getenv("DEJAG_THREADS"); env && *env) {
        char* endPtr = nullptr;
        long value = std::strtol(env, &endPtr, 10);
        if (*endPtr != '\0' || value < 0 || value > 1024)
            throw Error("DEJAG_THREADS='" + std::string(env) +
                        "' is not a thread count from 1 to 1024 (or 0, the core count)");
        if (value > 0) return int(value);
    }
    return hardwareThreadCount();
}

std::mutex g_poolMutex;
std::unique_ptr<ThreadPool> g_pool;

ThreadPool& pool() {
    std::lock_guard<std::mutex> lock(g_poolMutex);
    if (!g_pool) {
        flushDenormalsOnThisThread();
        g_pool = std::make_unique<ThreadPool>(defaultThreadCount());
    }
    return *g_pool;
}

}  // namespace

int hardwareThreadCount() {
    return std::max(1u, std::thread::hardware_concurrency());
}

int threadCount() {
    return pool().threads();
}

void setThreadCount(int threads) {
    if (threads < 0 || threads > 1024)
        throw Error("thread count " + std::to_string(threads) + " is not in 1..1024");
    int wanted = threads == 0 ? defaultThreadCount() : threads;
    std::lock_guard<std::mutex> lock(g_poolMutex);
    flushDenormalsOnThisThread();
    if (g_pool && g_pool->threads() == wanted) return;
    g_pool.reset();
    g_pool = std::make_unique<ThreadPool>(wanted);
}

void parallelFor(int64_t begin, int64_t end, int64_t grain, const ParallelBody& body) {
    pool().parallelFor(begin, end, grain, body);
}

void flushDenormalsOnThisThread() {
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

}  // namespace dejag
