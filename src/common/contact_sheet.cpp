#include "raindrop/common/contact_sheet.h"

#include <algorithm>

#include <opencv2/imgproc.hpp>

namespace raindrop {

cv::Mat to_rgb8(const cv::Mat& image) {
  cv::Mat eight;
  if (image.depth() == CV_16U) {
    image.convertTo(eight, CV_8U, 1.0 / 257.0);
  } else {
    eight = image;
  }
  cv::Mat rgb;
  switch (eight.channels()) {
    case 1: cv::cvtColor(eight, rgb, cv::COLOR_GRAY2RGB); break;
    case 2: {  // grey + alpha
      cv::Mat grey;
      cv::extractChannel(eight, grey, 0);
      cv::cvtColor(grey, rgb, cv::COLOR_GRAY2RGB);
      break;
    }
    case 4: cv::cvtColor(eight, rgb, cv::COLOR_RGBA2RGB); break;
    default: rgb = eight;
  }
  return rgb;
}

namespace {

// A panel's size on the sheet: panel_width wide, keeping the image's aspect ratio, but at most
// kMaxPanelAspect times as tall as panel_width (then narrower): a 1-pixel-wide frame of 8000
// rows would otherwise become a 512 x 4,096,000 panel of 6 GB.
constexpr int kMaxPanelAspect = 4;
cv::Size panel_size(const cv::Mat& p, int panel_width) {
  const double scale = std::min(static_cast<double>(panel_width) / p.cols,
                                static_cast<double>(kMaxPanelAspect) * panel_width / p.rows);
  return {std::clamp(static_cast<int>(std::lround(p.cols * scale)), 1, panel_width),
          std::clamp(static_cast<int>(std::lround(p.rows * scale)), 1, kMaxPanelAspect * panel_width)};
}

}  // namespace

cv::Mat make_contact_sheet(const std::vector<std::vector<cv::Mat>>& rows,
                           const std::vector<std::string>& column_titles,
                           const std::vector<std::string>& row_captions, int panel_width) {
  constexpr int kGap = 6, kTitle = 30, kCaption = 22;
  size_t columns = column_titles.size();
  for (const auto& r : rows) columns = std::max(columns, r.size());
  std::vector<int> heights;
  for (const auto& r : rows) {
    int h = 0;
    for (const auto& p : r) {
      if (!p.empty()) h = std::max(h, panel_size(p, panel_width).height);
    }
    heights.push_back(h);
  }
  int total_h = kTitle;
  for (size_t i = 0; i < rows.size(); ++i) total_h += kCaption + heights[i] + kGap;
  const int total_w = static_cast<int>(columns) * (panel_width + kGap) + kGap;
  cv::Mat sheet(total_h, total_w, CV_8UC3, cv::Scalar(32, 32, 32));
  const auto font = cv::FONT_HERSHEY_SIMPLEX;
  for (size_t c = 0; c < column_titles.size(); ++c) {
    cv::putText(sheet, column_titles[c], {kGap + static_cast<int>(c) * (panel_width + kGap) + 4, 21}, font, 0.6,
                cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  }
  int y = kTitle;
  for (size_t r = 0; r < rows.size(); ++r) {
    if (r < row_captions.size()) {
      cv::putText(sheet, row_captions[r], {kGap + 4, y + 16}, font, 0.45, cv::Scalar(200, 200, 200), 1, cv::LINE_AA);
    }
    y += kCaption;
    for (size_t c = 0; c < rows[r].size(); ++c) {
      const cv::Mat& p = rows[r][c];
      if (p.empty()) continue;
      cv::Mat scaled;
      const cv::Size size = panel_size(p, panel_width);
      cv::resize(to_rgb8(p), scaled, size, 0, 0, p.cols > size.width ? cv::INTER_AREA : cv::INTER_NEAREST);
      scaled.copyTo(sheet(cv::Rect(kGap + static_cast<int>(c) * (panel_width + kGap), y, scaled.cols, scaled.rows)));
    }
    y += heights[r] + kGap;
  }
  return sheet;
}

}  // namespace raindrop
