// Counts heap allocations made by the test process (global operator new is replaced in
// tests/alloc_counter.cpp), so a test can prove that a hot path allocates nothing.
#pragma once

#include <cstdint>

namespace dejag::testing {

int64_t allocationCount();

}  // namespace dejag::testing
