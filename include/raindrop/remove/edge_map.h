#pragma once
// The edge map E of the paper's eq. 4 (docs/CONTRACTS.md section 2, step 2), the extra input
// of the 3RN.
//
// For every pixel: the sum over the colour channels of the absolute differences to its 4
// neighbours, divided by 4; at the image border the missing neighbour is the pixel itself.
// The float32 order of operations is the one of tools/raindrop_tools/edge.py, so that C++,
// numpy and torch agree bit for bit:
//     d = ((|x - right| + |x - left|) + |x - below|) + |x - above|   per channel
//     E = ((d_R + d_G) + d_B) * 0.25
// (The build uses -ffp-contract=off, so no fused multiply-add changes the rounding.)
#include <opencv2/core.hpp>

namespace raindrop::removal {

// CV_32FC3 (any values) -> CV_32FC1 of the same size.
cv::Mat edge_map(const cv::Mat& rgb);

}  // namespace raindrop::removal
