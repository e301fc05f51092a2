// TripleBuffer: hand-over semantics, and a two-thread stress test that
// checks every taken slot is one whole publication, newer than the last
// (run under TSan by tools/test.sh).
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

#include "big_item.hpp"
#include "stemd/base/triple_buffer.hpp"

using stemd::base::TripleBuffer;

using Big = stemd::test::BigItem<256>;

TEST(TripleBuffer, NothingToTakeBeforeThePublication)
{
    TripleBuffer<int> buffer;
    EXPECT_FALSE(buffer.take());
    buffer.write_slot() = 7;
    EXPECT_FALSE(buffer.take()) << "an unpublished write is not visible";
    buffer.publish();
    ASSERT_TRUE(buffer.take());
    EXPECT_EQ(buffer.read_slot(), 7);
    EXPECT_FALSE(buffer.take()) << "one publication is taken once";
    EXPECT_EQ(buffer.read_slot(), 7) << "the taken slot stays readable";
    EXPECT_EQ(buffer.published(), 1u);
}

TEST(TripleBuffer, TheReaderGetsTheNewestPublication)
{
    TripleBuffer<int> buffer;
    for (int i = 1; i <= 5; ++i) {
        buffer.write_slot() = i;
        buffer.publish();
    }
    ASSERT_TRUE(buffer.take());
    EXPECT_EQ(buffer.read_slot(), 5);
    buffer.write_slot() = 6;
    buffer.publish();
    ASSERT_TRUE(buffer.take());
    EXPECT_EQ(buffer.read_slot(), 6);
}

TEST(TripleBuffer, WriterNeverWritesTheSlotTheReaderHolds)
{
    // The three slots are distinct objects; while the reader holds one, the
    // writer cycles through the other two.
    TripleBuffer<int> buffer;
    buffer.write_slot() = 1;
    buffer.publish();
    ASSERT_TRUE(buffer.take());
    const int* held = &buffer.read_slot();
    for (int i = 0; i < 10; ++i) {
        EXPECT_NE(&buffer.write_slot(), held);
        buffer.write_slot() = 100 + i;
        buffer.publish();
    }
    EXPECT_EQ(*held, 1);
}

TEST(TripleBuffer, InitRunsOncePerSlot)
{
    int calls = 0;
    TripleBuffer<std::vector<int>> buffer([&calls](std::vector<int>& slot) {
        slot.resize(100);
        ++calls;
    });
    EXPECT_EQ(calls, 3);
    EXPECT_EQ(buffer.write_slot().size(), 100u);
    EXPECT_EQ(buffer.read_slot().size(), 100u);
}

TEST(TripleBuffer, TwoThreadsSeeWholeNewerPublications)
{
    TripleBuffer<Big> buffer;
    constexpr std::uint64_t kPublications = 200'000;
    std::atomic<bool> done{false};
    std::thread writer([&] {
        for (std::uint64_t i = 1; i <= kPublications; ++i) {
            Big& slot = buffer.write_slot();
            slot.seq = i;
            slot.payload.fill(i);
            buffer.publish();
        }
        done.store(true, std::memory_order_release);
    });
    std::uint64_t last = 0, taken = 0, torn = 0, older = 0;
    for (;;) {
        const bool finished = done.load(std::memory_order_acquire);
        if (buffer.take()) {
            const Big& slot = buffer.read_slot();
            for (const std::uint64_t v : slot.payload)
                torn += v != slot.seq;
            older += slot.seq <= last;
            last = slot.seq;
            ++taken;
        } else if (finished) {
            break;
        }
    }
    writer.join();
    EXPECT_EQ(torn, 0u);
    EXPECT_EQ(older, 0u);
    EXPECT_EQ(last, kPublications) << "the last publication is always taken";
    EXPECT_GT(taken, 0u);
    EXPECT_EQ(buffer.published(), kPublications);
}
