// mask.h: the detection threshold and the elliptical dilation.
#include <opencv2/imgproc.hpp>

#include "raindrop/common/error.h"
#include "raindrop/remove/mask.h"
#include "raindrop/remove/model.h"
#include "remove_test_util.h"

namespace removetest {
namespace {

using namespace raindrop::removal;

TEST(Mask, ThresholdIsStrictAndComparedInFloat) {
  const float t = 0.3f;  // the float nearest to 0.3 is slightly above it
  cv::Mat p = (cv::Mat_<float>(1, 5) << 0.0f, std::nextafter(t, 0.0f), t, std::nextafter(t, 1.0f),
               std::numeric_limits<float>::quiet_NaN());
  cv::Mat m(1, 5, CV_8U, cv::Scalar(7));
  threshold_mask(p, 0.3, m);
  EXPECT_EQ(m.at<unsigned char>(0, 0), 0);
  EXPECT_EQ(m.at<unsigned char>(0, 1), 0);
  EXPECT_EQ(m.at<unsigned char>(0, 2), 0) << "P == threshold must not count (strictly greater)";
  EXPECT_EQ(m.at<unsigned char>(0, 3), 1);
  EXPECT_EQ(m.at<unsigned char>(0, 4), 0) << "NaN must not count";
}

TEST(Mask, DilationIsTheOpenCvEllipseWithOutsidePixelsNotCounting) {
  cv::Mat m0(9, 11, CV_8U, cv::Scalar(0));
  m0.at<unsigned char>(4, 5) = 1;
  m0.at<unsigned char>(0, 0) = 1;  // at the border: must not wrap or smear
  EXPECT_EQ(cv::countNonZero(dilate_mask(m0, 1) != m0), 0);
  const cv::Mat m3 = dilate_mask(m0, 3);
  // 3x3 ellipse = a plus: 5 pixels around (4,5), 3 inside the image around (0,0).
  EXPECT_EQ(cv::countNonZero(m3), 5 + 3);
  EXPECT_EQ(m3.at<unsigned char>(3, 5), 1);
  EXPECT_EQ(m3.at<unsigned char>(3, 4), 0);
  // k = 5 around a single pixel: exactly the structuring element.
  cv::Mat one(5, 5, CV_8U, cv::Scalar(0));
  one.at<unsigned char>(2, 2) = 1;
  const cv::Mat k5 = cv::getStructuringElement(cv::MORPH_ELLIPSE, {5, 5});
  EXPECT_EQ(cv::countNonZero(dilate_mask(one, 5) != k5), 0);
  // A full mask stays full (the border value must not erode it).
  const cv::Mat full(6, 6, CV_8U, cv::Scalar(1));
  EXPECT_EQ(cv::countNonZero(dilate_mask(full, 7)), 36);
  EXPECT_THROW(dilate_mask(one, 0), raindrop::Error);
}

TEST(Mask, DilationForAreaIsTheOddSizeNearestGrowthTimesTheDiameter) {
  const double disk20 = M_PI * 10 * 10;  // a disk 20 px across
  EXPECT_EQ(dilation_for_area(disk20, 3, 0.0), 3) << "growth 0: k";
  EXPECT_EQ(dilation_for_area(disk20, 3, 0.35), 7) << "0.35 x 20 = 7";
  EXPECT_EQ(dilation_for_area(disk20, 3, 0.45), 9) << "0.45 x 20 = 9";
  EXPECT_EQ(dilation_for_area(disk20, 3, 0.42), 9) << "8.4: nearer 9 than 7";
  EXPECT_EQ(dilation_for_area(disk20, 3, 0.28), 5) << "5.6: nearer 5 than 7";
  EXPECT_EQ(dilation_for_area(disk20, 11, 0.35), 11) << "never below k";
  EXPECT_EQ(dilation_for_area(1, 3, 0.35), 3) << "a one-pixel drop keeps k";
  EXPECT_EQ(dilation_for_area(1e12, 3, 10.0), kMaxDilation) << "capped";
  EXPECT_EQ(dilation_for_area(0, 3, 0.35), 3);
}

// `mask` with only the 8-connected component that holds (y, x).
cv::Mat component_at(const cv::Mat& mask, int y, int x) {
  cv::Mat labels;
  cv::connectedComponents(mask, labels, 8, CV_32S);
  cv::Mat only = labels == labels.at<int>(y, x);
  return only / 255;
}

TEST(Mask, DilationBySizeDilatesEachDropByItsOwnSize) {
  cv::Mat m0(60, 80, CV_8U, cv::Scalar(0));
  cv::circle(m0, {40, 30}, 10, cv::Scalar(1), cv::FILLED);  // 317 px: d = 20.1, 0.35 d = 7.03 -> 7
  cv::circle(m0, {4, 4}, 10, cv::Scalar(1), cv::FILLED);    // cut by the corner: 186 px, d = 15.4, 0.35 d = 5.4 -> 5
  m0.at<unsigned char>(55, 75) = 1;                         // one pixel: k
  m0.at<unsigned char>(50, 10) = 1;                         // two pixels that touch at a corner:
  m0.at<unsigned char>(51, 11) = 1;                         // one drop (8-connected)
  ASSERT_EQ(cv::countNonZero(component_at(m0, 4, 4)), 186);

  EXPECT_EQ(cv::countNonZero(dilate_mask_by_size(m0, 3, 0.0) != dilate_mask(m0, 3)), 0) << "growth 0";

  const cv::Mat grown = dilate_mask_by_size(m0, 3, 0.35);
  cv::Mat expected = dilate_mask(component_at(m0, 30, 40), 7) | dilate_mask(component_at(m0, 4, 4), 5) |
                     dilate_mask(component_at(m0, 55, 75), 3) | dilate_mask(component_at(m0, 50, 10), 3);
  EXPECT_EQ(cv::countNonZero(grown != expected), 0);
  EXPECT_EQ(grown.at<unsigned char>(30, 53), 1) << "the large drop's mask reaches 3 px past its edge";
  EXPECT_EQ(grown.at<unsigned char>(30, 54), 0);
  EXPECT_EQ(grown.at<unsigned char>(53, 75), 0) << "the one-pixel drop keeps k = 3";
  double lo = 0, hi = 0;
  cv::minMaxLoc(grown, &lo, &hi);
  EXPECT_EQ(hi, 1.0) << "0/1, as dilate_mask";
}

// A grown drop cut by the bottom-right corner: its box, grown by the kernel's reach, is clipped on
// that side, and the result is still the whole-image dilation.
TEST(Mask, DilationBySizeAtTheFarCorner) {
  cv::Mat m0(40, 50, CV_8U, cv::Scalar(0));
  cv::circle(m0, {47, 37}, 12, cv::Scalar(1), cv::FILLED);
  const int area = cv::countNonZero(m0);
  const int k = dilation_for_area(area, 3, 0.5);
  ASSERT_GT(k, 3) << area << " px";
  EXPECT_EQ(cv::countNonZero(dilate_mask_by_size(m0, 3, 0.5) != dilate_mask(m0, k)), 0) << "k " << k;
}

}  // namespace
}  // namespace removetest
