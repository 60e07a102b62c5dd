// The scratch pool hands a released buffer to the next request that fits, keeps a buffer
// while any matrix header still uses it, and keeps at most kScratchBuffersKept free.
#include <vector>

#include <gtest/gtest.h>

#include "raindrop/render/scratch_pool.h"

using namespace raindrop;

TEST(ScratchPool, AReleasedMatrixIsReusedAndACopyKeepsItAlive) {
  const uchar* first = nullptr;
  {
    cv::Mat m = scratch_mat(123, 457, CV_32FC3);
    ASSERT_TRUE(m.isContinuous());
    EXPECT_EQ(m.total(), 123u * 457u);
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(m.data) % 64, 0u);
    first = m.data;
  }
  cv::Mat again = scratch_mat(123, 457, CV_32FC3);
  EXPECT_EQ(again.data, first);  // the same buffer, not new memory
  cv::Mat copy = again;          // a second header
  again.release();
  cv::Mat other = scratch_mat(123, 457, CV_32FC3);
  EXPECT_NE(other.data, first);  // still in use through `copy`
  copy.setTo(cv::Scalar::all(1));
  EXPECT_EQ(copy.at<cv::Vec3f>(122, 456), cv::Vec3f(1, 1, 1));
}

TEST(ScratchPool, BytesComeBackAndTheSmallestThatFitsIsChosen) {
  // Whatever earlier tests left free is held here, so that only this test's buffers are free.
  std::vector<ScratchBytes> held;
  for (int n = scratch_buffers_free(); n > 0; --n) held.push_back(scratch_bytes(1));
  ASSERT_EQ(scratch_buffers_free(), 0);
  std::byte* big = nullptr;
  std::byte* small = nullptr;
  {
    ScratchBytes a = scratch_bytes(1 << 20), b = scratch_bytes(1 << 16);
    big = a.get();
    small = b.get();
  }
  ScratchBytes c = scratch_bytes(1000);  // both fit: the smaller is taken
  EXPECT_EQ(c.get(), small);
  ScratchBytes d = scratch_bytes(1 << 19);
  EXPECT_EQ(d.get(), big);
}

TEST(ScratchPool, KeepsABoundedNumberOfFreeBuffers) {
  {
    std::vector<ScratchBytes> many;
    for (int i = 0; i < 3 * kScratchBuffersKept; ++i) many.push_back(scratch_bytes(4096 + i));
  }
  EXPECT_EQ(scratch_buffers_free(), kScratchBuffersKept);
}
