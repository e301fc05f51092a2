// The counters every frame source shares: what the capture thread adds is
// what a snapshot reads, and replay numbers its frames with the count before.
#include <gtest/gtest.h>

#include "stemd/drivers/source_counters.hpp"

using namespace stemd::drivers;

TEST(SourceCounterCells, ASnapshotReadsEachCounter)
{
    SourceCounterCells cells;
    EXPECT_EQ(SourceCounterCells::bump(cells.delivered), 0u);
    EXPECT_EQ(SourceCounterCells::bump(cells.delivered), 1u);
    SourceCounterCells::bump(cells.timeouts);
    SourceCounterCells::bump(cells.errors);
    SourceCounterCells::bump(cells.errors);
    SourceCounterCells::bump(cells.reopens);
    SourceCounterCells::bump(cells.corrupt);
    SourceCounterCells::bump(cells.bad_size);
    SourceCounterCells::bump(cells.bad_size);
    SourceCounterCells::bump(cells.bad_size);

    const SourceCounters c = cells.load();
    EXPECT_EQ(c.delivered, 2u);
    EXPECT_EQ(c.timeouts, 1u);
    EXPECT_EQ(c.errors, 2u);
    EXPECT_EQ(c.reopens, 1u);
    EXPECT_EQ(c.corrupt, 1u);
    EXPECT_EQ(c.bad_size, 3u);
    // Replay's own: no camera has them.
    EXPECT_EQ(c.loops, 0u);
    EXPECT_EQ(c.late, 0u);
    EXPECT_EQ(c.worst_lateness_ms, 0.0);
}
