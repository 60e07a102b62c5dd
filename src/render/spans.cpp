#include "raindrop/render/spans.h"

#include <algorithm>

namespace raindrop {

void merge_spans(std::vector<Span>& spans) {
  std::sort(spans.begin(), spans.end());
  std::vector<Span> merged;
  for (const auto& sp : spans) {
    if (!merged.empty() && sp.first <= merged.back().second + 1) {
      merged.back().second = std::max(merged.back().second, sp.second);
    } else {
      merged.push_back(sp);
    }
  }
  spans = std::move(merged);
}

}  // namespace raindrop
