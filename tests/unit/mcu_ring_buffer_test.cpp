// The SPSC byte ring used by the MCU link drivers (hal/mcu/include/phalanx/mcu/ring_buffer.h).
#include <gtest/gtest.h>

#include <cstdint>
#include <thread>
#include <vector>

#include "../../hal/mcu/include/phalanx/mcu/ring_buffer.h"

using phalanx::mcu::ByteRing;

TEST(McuByteRing, StartsEmptyWithFullCapacityFree) {
  ByteRing<16> r;
  EXPECT_TRUE(r.empty());
  EXPECT_EQ(r.space(), 16u);
  uint8_t b = 0;
  EXPECT_FALSE(r.pop(b));
}

TEST(McuByteRing, KeepsFifoOrderAcrossTheWrapPoint) {
  ByteRing<8> r;
  uint8_t out[8];
  for (int round = 0; round < 50; ++round) {
    const uint8_t src[5] = {uint8_t(round), uint8_t(round + 1), uint8_t(round + 2), uint8_t(round + 3), uint8_t(round + 4)};
    ASSERT_EQ(r.write(src, 5), 5u);
    ASSERT_EQ(r.read(out, 8), 5u);
    for (int i = 0; i < 5; ++i) EXPECT_EQ(out[i], src[i]);
  }
}

TEST(McuByteRing, RefusesBytesWhenFullAndCountsPushOverflows) {
  ByteRing<4> r;
  for (uint8_t i = 0; i < 4; ++i) EXPECT_TRUE(r.push(i));
  EXPECT_FALSE(r.push(9));
  EXPECT_EQ(r.overflows(), 1u);
  const uint8_t more[3] = {1, 2, 3};
  EXPECT_EQ(r.write(more, 3), 0u);
  uint8_t b = 0;
  ASSERT_TRUE(r.pop(b));
  EXPECT_EQ(b, 0);
  EXPECT_EQ(r.write(more, 3), 1u);
  EXPECT_EQ(r.size(), 4u);
}

TEST(McuByteRing, IndicesSurviveThe32BitWrap) {
  // 2^32 / 4 pushes would take long; instead check size() arithmetic across many full cycles stays exact.
  ByteRing<4> r;
  uint8_t b = 0;
  for (uint32_t i = 0; i < 100000; ++i) {
    ASSERT_TRUE(r.push(static_cast<uint8_t>(i)));
    ASSERT_TRUE(r.pop(b));
    ASSERT_EQ(b, static_cast<uint8_t>(i));
  }
  EXPECT_TRUE(r.empty());
}

TEST(McuByteRing, OneProducerThreadAndOneConsumerThreadSeeEveryByteInOrder) {
  static ByteRing<64> r;  // static: the ring is as large as on the MCU, keep it off the test's stack
  constexpr uint32_t kBytes = 200000;
  std::thread producer([] {
    for (uint32_t i = 0; i < kBytes;) {
      if (r.push(static_cast<uint8_t>(i * 7u))) ++i;
    }
  });
  uint32_t got = 0;
  bool in_order = true;
  while (got < kBytes) {
    uint8_t b = 0;
    if (r.pop(b)) {
      in_order = in_order && b == static_cast<uint8_t>(got * 7u);
      ++got;
    }
  }
  producer.join();
  EXPECT_TRUE(in_order);
}

// write()/read() copy in at most two pieces around the end of the storage (issue 20): every split against a model.
TEST(McuByteRing, BlockWritesAndReadsOfEveryLengthMatchAQueueModel) {
  ByteRing<16> r;
  std::vector<uint8_t> model;  // bytes in the ring, oldest first
  uint32_t seed = 12345;
  auto next = [&seed] { return seed = seed * 1103515245u + 12345u, (seed >> 16) & 0x7FFFu; };
  uint8_t counter = 0;
  for (int step = 0; step < 20000; ++step) {
    if (next() % 2 == 0) {
      uint8_t src[20];
      const size_t len = next() % 21;
      for (size_t i = 0; i < len; ++i) src[i] = counter++;
      const size_t fit = len < 16 - model.size() ? len : 16 - model.size();
      ASSERT_EQ(r.write(src, len), fit);
      model.insert(model.end(), src, src + fit);
      counter = static_cast<uint8_t>(counter - (len - fit));
    } else {
      uint8_t dst[20];
      const size_t len = next() % 21;
      const size_t got = r.read(dst, len);
      ASSERT_EQ(got, len < model.size() ? len : model.size());
      for (size_t i = 0; i < got; ++i) ASSERT_EQ(dst[i], model[i]) << "step " << step;
      model.erase(model.begin(), model.begin() + static_cast<long>(got));
    }
    ASSERT_EQ(r.size(), model.size());
  }
}
