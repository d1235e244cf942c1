#include "lookup/coarse/descriptor_index.h"

#include <gtest/gtest.h>

#include "synthetic_route.h"

namespace lookup::coarse {
namespace {

using testing::SyntheticRoute;

TEST(DescriptorIndex, FindsEachReferenceAndItsLookAlikes) {
    const CoarseOptions o;
    SyntheticRoute route(3000, 300, 21);  // every tile type recurs about 10 times
    ReferenceDescriptors refs(o);
    for (int i = 0; i < route.places(); ++i) refs.add(i, computeDescriptor(route.image(i, 4.0), o));
    const DescriptorIndex index(refs);
    ASSERT_EQ(index.size(), refs.size());
    EXPECT_LE(index.dimensions(), DescriptorIndex::kDimensions);

    int self_first = 0, same_type = 0, returned = 0;
    for (int i = 0; i < route.places(); i += 7) {
        // A noisier, darker view of place i: its nearest references are places of its tile type.
        const auto query = computeDescriptor(route.image(i, 8.0, 0.7, 25.0), o);
        const auto nearest = index.nearest(query, 8);
        ASSERT_FALSE(nearest.empty());
        self_first += index.nearest(refs.descriptor(i), 1).front() == i;
        for (long j : nearest) {
            ++returned;
            same_type += route.typeAt(static_cast<int>(j)) == route.typeAt(i);
        }
    }
    const int queries = (route.places() + 6) / 7;
    EXPECT_GE(self_first, 0.95 * queries);  // approximate, but nearly always exact on itself
    EXPECT_GE(same_type, 0.8 * returned);   // random places would be 1 in 300
}

TEST(DescriptorIndex, RefusesEmptySequencesAndForeignDescriptors) {
    const CoarseOptions o;
    EXPECT_THROW(DescriptorIndex{ReferenceDescriptors(o)}, std::invalid_argument);
    SyntheticRoute route(50, 5, 3);
    ReferenceDescriptors refs(o);
    for (int i = 0; i < 50; ++i) refs.add(i, computeDescriptor(route.image(i, 4.0), o));
    const DescriptorIndex index(refs);
    EXPECT_THROW(index.nearest(Descriptor(10, 128), 3), std::invalid_argument);
    EXPECT_EQ(index.nearest(refs.descriptor(3), 500).size(), 50u);  // k is capped
}

TEST(DescriptorIndex, IdenticalReferencesStillAnswer) {
    // A survey that stood still (or a featureless stretch): no variance for the projection,
    // no split for the kd-trees; the index must still build and answer, not hang.
    const CoarseOptions o;
    SyntheticRoute route(10, 3, 4);
    const Descriptor same = computeDescriptor(route.image(2.0, 0.0), o);
    ReferenceDescriptors refs(o);
    for (int i = 0; i < 1500; ++i) refs.add(i, same);
    const DescriptorIndex index(refs);
    const auto nearest = index.nearest(same, 8);
    EXPECT_EQ(nearest.size(), 8u);
    for (long j : nearest) EXPECT_LT(j, 1500);
}

}  // namespace
}  // namespace lookup::coarse
