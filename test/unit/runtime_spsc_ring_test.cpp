// SpscRing: edges, drop counting, overwrite, and two-thread stress tests
// that check every item (run under TSan by tools/test.sh).
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

#include "big_item.hpp"
#include "stemd/base/spsc_ring.hpp"

using stemd::base::SpscRing;

using Big = stemd::test::BigItem<64>;

TEST(SpscRing, RejectsZeroCapacity)
{
    EXPECT_THROW(SpscRing<int>(0), std::invalid_argument);
}

TEST(SpscRing, EmptyAndFullEdgesCountDrops)
{
    // int: small and trivially copyable, so atomic cells (try_push/try_pop).
    SpscRing<int> ring(3);
    int out = -1;
    EXPECT_TRUE(ring.empty());
    EXPECT_FALSE(ring.try_pop(out));
    for (int i = 0; i < 3; ++i)
        EXPECT_TRUE(ring.try_push(i));
    EXPECT_EQ(ring.size(), 3u);
    EXPECT_FALSE(ring.try_push(99));
    EXPECT_FALSE(ring.try_push(100));
    EXPECT_EQ(ring.dropped(), 2u);
    ASSERT_TRUE(ring.try_pop(out));
    EXPECT_EQ(out, 0);
    EXPECT_TRUE(ring.try_push(3));
    for (int expected = 1; expected <= 3; ++expected) {
        ASSERT_TRUE(ring.try_pop(out));
        EXPECT_EQ(out, expected);
    }
    EXPECT_FALSE(ring.try_pop(out));
    EXPECT_TRUE(ring.empty());
    EXPECT_EQ(ring.dropped(), 2u);
}

TEST(SpscRing, PlainCellsEdges)
{
    // Big: plain cells (front/pop, claim/publish).
    SpscRing<Big> ring(2);
    EXPECT_EQ(ring.front(), nullptr);
    Big item;
    for (std::uint64_t i = 0; i < 2; ++i) {
        item.seq = i;
        EXPECT_TRUE(ring.try_push(item));
    }
    EXPECT_FALSE(ring.try_push(item));
    EXPECT_EQ(ring.dropped(), 1u);
    EXPECT_EQ(ring.claim(), nullptr) << "claim on a full ring";
    EXPECT_EQ(ring.dropped(), 1u) << "claim() does not count: the caller decides";
    ASSERT_NE(ring.front(), nullptr);
    EXPECT_EQ(ring.front()->seq, 0u);
    ring.pop();
    ASSERT_TRUE(ring.try_pop(item));
    EXPECT_EQ(item.seq, 1u);
    EXPECT_EQ(ring.front(), nullptr);
}

TEST(SpscRing, CapacityOneWrapsManyTimes)
{
    SpscRing<int> ring(1);
    for (int i = 0; i < 1000; ++i) {
        ASSERT_TRUE(ring.try_push(i));
        ASSERT_FALSE(ring.try_push(-1));
        int out = -1;
        ASSERT_TRUE(ring.try_pop(out));
        ASSERT_EQ(out, i);
    }
    EXPECT_EQ(ring.dropped(), 1000u);
}

TEST(SpscRing, ClaimPublishBuildsInPlace)
{
    SpscRing<Big> ring(2);
    Big* a = ring.claim();
    ASSERT_NE(a, nullptr);
    a->seq = 7;
    a->payload[63] = 42;
    EXPECT_TRUE(ring.empty()) << "not visible before publish()";
    ring.publish();
    Big* b = ring.claim();
    ASSERT_NE(b, nullptr);
    EXPECT_NE(a, b);
    // Not publishing abandons the claim: the same cell comes back.
    EXPECT_EQ(ring.claim(), b);
    ASSERT_NE(ring.front(), nullptr);
    EXPECT_EQ(ring.front(), a);
    EXPECT_EQ(ring.front()->payload[63], 42u);
    ring.pop();
    EXPECT_EQ(ring.front(), nullptr);
}

TEST(SpscRing, OverwriteHandsBackTheOldest)
{
    std::array<int, 5> items{0, 1, 2, 3, 4};
    SpscRing<int*> ring(3);
    int* evicted = nullptr;
    for (int i = 0; i < 3; ++i)
        EXPECT_FALSE(ring.try_push_overwrite(&items[i], evicted));
    EXPECT_EQ(ring.overwritten(), 0u);
    EXPECT_TRUE(ring.try_push_overwrite(&items[3], evicted));
    EXPECT_EQ(evicted, &items[0]);
    EXPECT_TRUE(ring.try_push_overwrite(&items[4], evicted));
    EXPECT_EQ(evicted, &items[1]);
    EXPECT_EQ(ring.overwritten(), 2u);
    EXPECT_EQ(ring.dropped(), 0u);
    int* out = nullptr;
    for (int expected = 2; expected <= 4; ++expected) {
        ASSERT_TRUE(ring.try_pop(out));
        EXPECT_EQ(*out, expected);
    }
    EXPECT_FALSE(ring.try_pop(out));
}

TEST(SpscRing, HeadAndTailAreOnSeparateCacheLines)
{
    // The point of the padding: producer and consumer never share a line.
    EXPECT_GE(sizeof(SpscRing<int>), 2 * stemd::base::kCacheLineBytes);
    EXPECT_EQ(alignof(SpscRing<int>), stemd::base::kCacheLineBytes);
}

// --- two threads -------------------------------------------------------------

constexpr std::uint64_t kStressItems = 200'000;

// drop_newest: every item the producer pushed arrives, in order; every item
// it did not push was counted as dropped.
TEST(SpscRingStress, DropNewestLosesOnlyCountedItems)
{
    SpscRing<std::uint64_t> ring(8);
    std::uint64_t pushed = 0;
    std::thread producer([&] {
        for (std::uint64_t seq = 0; seq < kStressItems; ++seq)
            pushed += ring.try_push(seq) ? 1 : 0;
    });
    std::uint64_t received = 0;
    std::uint64_t last = 0;
    bool first = true, in_order = true;
    std::thread consumer([&] {
        std::uint64_t v = 0;
        // Done when every item is accounted for: received or counted as dropped.
        for (;;) {
            if (ring.try_pop(v)) {
                in_order = in_order && (first || v > last);
                first = false;
                last = v;
                ++received;
            } else if (received + ring.dropped() == kStressItems) {
                break;
            } else {
                std::this_thread::yield();
            }
        }
    });
    producer.join();
    consumer.join();
    EXPECT_TRUE(in_order);
    EXPECT_EQ(received, pushed);
    EXPECT_EQ(received + ring.dropped(), kStressItems);
}

// Back-pressure (fast replay): the producer waits for room, so every item
// arrives exactly once, in order, built in place.
TEST(SpscRingStress, InPlaceItemsArriveCompleteAndInOrder)
{
    SpscRing<Big> ring(4);
    std::thread producer([&] {
        for (std::uint64_t seq = 0; seq < kStressItems / 4; ++seq) {
            Big* cell = nullptr;
            while ((cell = ring.claim()) == nullptr)
                std::this_thread::yield();
            cell->seq = seq;
            cell->payload.fill(seq * 3 + 1);
            ring.publish();
        }
    });
    std::uint64_t expected = 0;
    bool intact = true;
    while (expected < kStressItems / 4) {
        const Big* cell = ring.front();
        if (cell == nullptr) {
            std::this_thread::yield();   // 2 cores, and other builds: let the producer run
            continue;
        }
        intact = intact && cell->seq == expected;
        for (const std::uint64_t word : cell->payload)
            intact = intact && word == expected * 3 + 1;
        ring.pop();
        ++expected;
    }
    producer.join();
    EXPECT_TRUE(intact);
    EXPECT_EQ(ring.dropped(), 0u);
}

// overwrite_oldest with pointer items, as the frame ring uses it: a pool of
// slots circulates (free ring back to the producer); every slot the consumer
// receives holds a sequence number greater than the last one, every evicted
// slot returns to the producer, and received + overwritten = produced.
TEST(SpscRingStress, OverwriteOldestLosesOnlyCountedItemsAndNoSlot)
{
    constexpr std::size_t kCapacity = 4;
    constexpr std::size_t kSlots = kCapacity + 2;
    std::array<std::uint64_t, kSlots> slots{};
    SpscRing<std::uint64_t*> frames(kCapacity);
    SpscRing<std::uint64_t*> free_slots(kSlots);
    for (auto& s : slots)
        ASSERT_TRUE(free_slots.try_push(&s));

    std::atomic<bool> producer_done{false};
    std::uint64_t no_free_slot = 0;
    std::uint64_t* hand = nullptr;   // the producer's slot; read after join
    std::thread producer([&] {
        for (std::uint64_t seq = 0; seq < kStressItems;) {
            if (hand == nullptr && !free_slots.try_pop(hand)) {
                ++no_free_slot;   // the pool size makes this impossible
                std::this_thread::yield();
                continue;
            }
            *hand = seq++;
            std::uint64_t* evicted = nullptr;
            hand = frames.try_push_overwrite(hand, evicted) ? evicted : nullptr;
        }
        producer_done.store(true, std::memory_order_release);
    });
    std::uint64_t received = 0, last = 0;
    bool first = true, in_order = true;
    for (;;) {
        std::uint64_t* slot = nullptr;
        if (frames.try_pop(slot)) {
            in_order = in_order && (first || *slot > last);
            first = false;
            last = *slot;
            ++received;
            ASSERT_TRUE(free_slots.try_push(slot));
        } else if (producer_done.load(std::memory_order_acquire) && frames.empty()) {
            break;
        } else {
            std::this_thread::yield();
        }
    }
    producer.join();
    EXPECT_TRUE(in_order);
    EXPECT_EQ(no_free_slot, 0u);
    EXPECT_EQ(received + frames.overwritten(), kStressItems);
    EXPECT_EQ(last, kStressItems - 1) << "the newest item is never the one overwritten";
    EXPECT_EQ(free_slots.size() + (hand != nullptr ? 1 : 0), kSlots) << "every slot came back";
}
