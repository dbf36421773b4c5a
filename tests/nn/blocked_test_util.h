// Test helpers for the blocked activation layout (nn/blocked.h).
#pragma once

#include <gtest/gtest.h>

#include "nn/blocked.h"

namespace dejag::testing {

// Every element of the border of a blocked tensor is zero: the next layer reads its padding there.
inline void expectZeroBorder(const float* data, const nn::BlockedShape& s) {
    for (int64_t n = 0; n < s.batch; ++n)
        for (int64_t y = -s.border; y < s.height + s.border; ++y)
            for (int64_t x = -s.border; x < s.width + s.border; ++x) {
                if (y >= 0 && y < s.height && x >= 0 && x < s.width) continue;
                for (int64_t cb = 0; cb < s.channelBlocks(); ++cb)
                    for (int c = 0; c < s.block; ++c) EXPECT_EQ(data[s.offset(n, cb, y, x) + c], 0.0f);
            }
}

}  // namespace dejag::testing
