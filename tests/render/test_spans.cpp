// Row spans: sorting and merging (shared by the tracer and the blur).
#include <gtest/gtest.h>

#include "raindrop/render/spans.h"

namespace raindrop {
namespace {

TEST(Spans, MergeSortsAndJoinsOverlappingAndTouchingIntervals) {
  std::vector<Span> s = {{10, 12}, {1, 3}, {4, 6}, {20, 20}, {11, 15}, {17, 18}};
  merge_spans(s);
  EXPECT_EQ(s, (std::vector<Span>{{1, 6}, {10, 15}, {17, 18}, {20, 20}}));
}

TEST(Spans, MergeKeepsContainedAndEmptyInputs) {
  std::vector<Span> s = {{0, 100}, {5, 7}};
  merge_spans(s);
  EXPECT_EQ(s, (std::vector<Span>{{0, 100}}));
  std::vector<Span> none;
  merge_spans(none);
  EXPECT_TRUE(none.empty());
}

}  // namespace
}  // namespace raindrop
