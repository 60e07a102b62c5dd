// contact_sheet.h: every image kind the programs write lands on a sheet as 8-bit RGB.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "raindrop/common/contact_sheet.h"

using raindrop::to_rgb8;

TEST(ContactSheet, PanelsOfEveryKindBecomeRgb8) {
  const cv::Mat grey(4, 6, CV_8UC1, cv::Scalar(90));
  const cv::Mat grey16(4, 6, CV_16UC1, cv::Scalar(90 * 257));
  const cv::Mat grey_alpha(4, 6, CV_8UC2, cv::Scalar(90, 7));
  const cv::Mat grey_alpha16(4, 6, CV_16UC2, cv::Scalar(90 * 257, 7));
  const cv::Mat rgb(4, 6, CV_8UC3, cv::Scalar(10, 20, 30));
  const cv::Mat rgba16(4, 6, CV_16UC4, cv::Scalar(10 * 257, 20 * 257, 30 * 257, 0));
  for (const cv::Mat* m : {&grey, &grey16, &grey_alpha, &grey_alpha16}) {
    const cv::Mat out = to_rgb8(*m);
    ASSERT_EQ(out.type(), CV_8UC3) << m->channels() << " channels, depth " << m->depth();
    EXPECT_EQ(out.at<cv::Vec3b>(2, 3), cv::Vec3b(90, 90, 90)) << m->channels() << " channels";  // alpha is not colour
  }
  for (const cv::Mat* m : {&rgb, &rgba16}) {
    const cv::Mat out = to_rgb8(*m);
    ASSERT_EQ(out.type(), CV_8UC3);
    EXPECT_EQ(out.at<cv::Vec3b>(1, 1), cv::Vec3b(10, 20, 30));  // a transparent pixel keeps its colour
  }
}

TEST(ContactSheet, SheetHoldsGreyAlphaPanels) {
  // The renderer's sheets and the remover's used to differ here: a grey+alpha panel must not
  // stop the sheet (OpenCV refuses to copy 2 channels into 3).
  const cv::Mat grey_alpha(40, 60, CV_8UC2, cv::Scalar(200, 255));
  const cv::Mat sheet = raindrop::make_contact_sheet({{grey_alpha, grey_alpha}}, {"a", "b"}, {"row"}, 60);
  ASSERT_EQ(sheet.type(), CV_8UC3);
  // The first panel's centre: below the title (30) and caption (22) rows, right of the gap (6).
  EXPECT_EQ(sheet.at<cv::Vec3b>(30 + 22 + 20, 6 + 30), cv::Vec3b(200, 200, 200));
}

TEST(ContactSheet, AThinTallPanelIsNarrowedInsteadOfStretched) {
  // A 1 x 8000 frame scaled to the panel width would be 512 x 4,096,000 (6 GB): panels are at
  // most 4 panel widths tall, and narrower to keep their aspect ratio.
  const cv::Mat thin(8000, 1, CV_8UC3, cv::Scalar(1, 2, 3));
  const cv::Mat wide(3, 1000, CV_8UC3, cv::Scalar(4, 5, 6));
  const cv::Mat sheet = raindrop::make_contact_sheet({{thin, wide}}, {"a", "b"}, {"row"}, 512);
  ASSERT_EQ(sheet.type(), CV_8UC3);
  EXPECT_EQ(sheet.rows, 30 + 22 + 4 * 512 + 6);
  EXPECT_EQ(sheet.cols, 2 * (512 + 6) + 6);
  EXPECT_EQ(sheet.at<cv::Vec3b>(30 + 22 + 100, 6), cv::Vec3b(1, 2, 3));  // the thin panel, one pixel wide
  EXPECT_EQ(sheet.at<cv::Vec3b>(30 + 22 + 100, 6 + 1), cv::Vec3b(32, 32, 32));  // background beside it
  EXPECT_EQ(sheet.at<cv::Vec3b>(30 + 22 + 1, 6 + 518 + 300), cv::Vec3b(4, 5, 6));  // the wide one, full width
  // An ordinary panel keeps the width it always had.
  const cv::Mat frame(256, 512, CV_8UC3, cv::Scalar(7, 8, 9));
  EXPECT_EQ(raindrop::make_contact_sheet({{frame}}, {"a"}, {"row"}, 128).rows, 30 + 22 + 64 + 6);
}
