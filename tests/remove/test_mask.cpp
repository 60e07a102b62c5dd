// mask.h: the detection threshold and the elliptical dilation.
#include <opencv2/imgproc.hpp>

#include "raindrop/common/error.h"
#include "raindrop/remove/mask.h"
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

}  // namespace
}  // namespace removetest
