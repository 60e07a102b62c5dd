#pragma once
// Contact sheets: a grid of panels (e.g. clean | rainy | mask per sample) with column titles
// and row captions, written as one PNG for people to look at.
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace raindrop {

// An 8-bit RGB view of any image the programs handle (8- or 16-bit grey, grey+alpha, RGB,
// RGBA; alpha dropped), for a panel.
cv::Mat to_rgb8(const cv::Mat& image);

// rows[r][c]: panels as to_rgb8 takes them, of any size; each is scaled to panel_width
// (keeping its aspect ratio), or narrower where that would make it more than 4 panel widths
// tall. Returns an RGB CV_8UC3 image.
cv::Mat make_contact_sheet(const std::vector<std::vector<cv::Mat>>& rows,
                           const std::vector<std::string>& column_titles,
                           const std::vector<std::string>& row_captions, int panel_width);

}  // namespace raindrop
