// base/communicator.h in one process (the job of several is tests/cli/mpi_test.cpp): the ordered sum adds
// the vectors in their order, and `together` passes an error through.
#include "base/communicator.h"

#include <gtest/gtest.h>

#include <vector>

#include "base/error.h"

namespace dejag {
namespace {

TEST(Communicator, OneProcessIsRankZeroOfOne) {
    EXPECT_EQ(communicator().rank(), 0);
    EXPECT_EQ(communicator().size(), 1);
    EXPECT_EQ(communicator().rankLabel(), "");
}

TEST(Communicator, SumInOrderAddsTheVectorsInTheirOrder) {
    // 1e8 + 1 - 1e8 is 0 in float taken in this order, 1 in another: the order shows in the bits.
    const std::vector<float> vectors = {1e8f,  2.0f, 1.0f, 3.0f,
                                        -1e8f, 5.0f, 7.0f, 7.0f};  // 4 of 2, + 1 unused
    std::vector<float> sum(2), scratch;
    sumInOrder(vectors.data(), 4, 3, 2, sum.data(), scratch);
    EXPECT_EQ(sum[0], (1e8f + 1.0f) + -1e8f);
    EXPECT_EQ(sum[0], 0.0f);
    EXPECT_EQ(sum[1], 2.0f + 3.0f + 5.0f);
    EXPECT_THROW(sumInOrder(vectors.data(), 1, 3, 2, sum.data(), scratch), Error);  // more than it holds
}

TEST(Communicator, TogetherPassesAnErrorThrough) {
    int ran = 0;
    together([&] { ++ran; });
    EXPECT_EQ(ran, 1);
    EXPECT_THROW(together([] { throw Error("no"); }), Error);
}

}  // namespace
}  // namespace dejag
