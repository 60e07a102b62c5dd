#pragma once
// Row spans: closed x-intervals [first, second] of one image row. The tracer records the
// pixels it traced as spans and the blur reads only the frame near them.
#include <utility>
#include <vector>

namespace raindrop {

using Span = std::pair<int, int>;

// Pixels [first, last] of one row whose camera rays can reach drop `drop`.
struct DropSpan {
  int first, last, drop;
};

// Sorts `spans` and merges those that overlap or touch ([1, 3] and [4, 6] become [1, 6]).
void merge_spans(std::vector<Span>& spans);

}  // namespace raindrop
