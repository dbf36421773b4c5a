#include "base/simd.h"

#include <atomic>
#include <cstdlib>
#include <string>

#include "base/error.h"

namespace dejag {
namespace {

SimdLevel detectCpuLevel() {
    __builtin_cpu_init();
    // libgcc's checks include the OS (XCR0) support for the wider registers.
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
        __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512vl") &&
        __builtin_cpu_supports("fma"))
        return SimdLevel::Avx512;
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return SimdLevel::Avx2;
    return SimdLevel::Scalar;
}

SimdLevel levelFromEnvironment() {
    SimdLevel cpu = cpuSimdLevel();
    const char* env = std::getenv("DEJAG_SIMD");
    if (!env || !*env) return cpu;
    std::optional<SimdLevel> wanted = parseSimdLevel(env);
    if (!wanted) throw Error("DEJAG_SIMD='" + std::string(env) + "' is not one of scalar, avx2, avx512");
    if (static_cast<int>(*wanted) > static_cast<int>(cpu))
        throw Error("DEJAG_SIMD=" + std::string(env) + " but this CPU supports at most " +
                    simdLevelName(cpu));
    return *wanted;
}

// -1: not chosen yet.
std::atomic<int> g_activeLevel{-1};

}  // namespace

SimdLevel cpuSimdLevel() {
    static const SimdLevel level = detectCpuLevel();
    return level;
}

SimdLevel activeSimdLevel() {
    int level = g_activeLevel.load(std::memory_order_relaxed);
    if (level < 0) {
        level = static_cast<int>(levelFromEnvironment());
        g_activeLevel.store(level, std::memory_order_relaxed);
    }
    return static_cast<SimdLevel>(level);
}

void setSimdLevel(SimdLevel level) {
    if (static_cast<int>(level) > static_cast<int>(cpuSimdLevel()))
        throw Error(std::string("SIMD level ") + simdLevelName(level) +
                    " is not supported by this CPU (best: " + simdLevelName(cpuSimdLevel()) + ")");
    g_activeLevel.store(static_cast<int>(level), std::memory_order_relaxed);
}

const char* simdLevelName(SimdLevel level) {
    switch (level) {
        case SimdLevel::Avx512:
            return "avx512";
        case SimdLevel::Avx2:
            return "avx2";
        case SimdLevel::Scalar:
            return "scalar";
    }
    return "unknown";
}

std::optional<SimdLevel> parseSimdLevel(std::string_view name) {
    if (name == "scalar") return SimdLevel::Scalar;
    if (name == "avx2") return SimdLevel::Avx2;
    if (name == "avx512") return SimdLevel::Avx512;
    return std::nullopt;
}

bool bf16Available() {
    static const bool cpu = [] {
        __builtin_cpu_init();
        return __builtin_cpu_supports("avx512bf16") != 0;
    }();
    return cpu && activeSimdLevel() == SimdLevel::Avx512;
}

int simdFloatLanes(SimdLevel level) {
    switch (level) {
        case SimdLevel::Avx512:
            return 16;
        case SimdLevel::Avx2:
            return 8;
        case SimdLevel::Scalar:
            return 1;
    }
    return 1;
}

}  // namespace dejag
