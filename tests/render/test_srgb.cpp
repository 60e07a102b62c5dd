// sRGB tables (srgb.h) against the formulas they replace in the layered defocus.
#include <cmath>
#include <cstdio>
#include <limits>

#include <gtest/gtest.h>

#include "raindrop/render/srgb.h"

using namespace raindrop;

// The encoder is the formula, code for code: on a dense sweep of [0, 1], next to every
// boundary between two codes, and at the odd values (negative, above 1, NaN, infinities).
TEST(Srgb, TableEncoderEqualsTheFormulaEverywhere) {
  const SrgbTables& t = SrgbTables::get();
  int checked = 0;
  for (int i = 0; i <= 1 << 22; ++i) {
    const float v = static_cast<float>(i) / (1 << 22);
    ASSERT_EQ(t.encode(v), linear_to_srgb8(v)) << v;
    ++checked;
  }
  for (int c = 1; c < 256; ++c) {
    float v = static_cast<float>(srgb_to_linear((c - 0.5) / 255.0));
    for (int k = 0; k < 8; ++k) v = std::nextafter(v, 0.0f);
    for (int k = 0; k < 16; ++k, v = std::nextafter(v, 2.0f)) {
      ASSERT_EQ(t.encode(v), linear_to_srgb8(v)) << "code " << c << " at " << v;
      ++checked;
    }
  }
  for (float v : {-1.0f, -0.0f, 0.0f, 1.0f, 1.5f, std::numeric_limits<float>::quiet_NaN(),
                  std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                  std::numeric_limits<float>::denorm_min()}) {
    EXPECT_EQ(t.encode(v), linear_to_srgb8(v)) << v;
  }
  EXPECT_GT(checked, 4'000'000);
}

// The decoder interpolates 4097 exact samples: within 2e-7 of the formula (an 8-bit step in
// linear light is at least 3e-4).
TEST(Srgb, TableDecoderIsWithin2e7OfTheFormula) {
  const SrgbTables& t = SrgbTables::get();
  double worst = 0;
  for (int i = 0; i <= 1 << 22; ++i) {
    const float v = static_cast<float>(i) / (1 << 22);
    worst = std::max(worst, std::abs(t.decode(v) - srgb_to_linear(v)));
  }
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", worst);
  RecordProperty("worst_decode_error", text);
  EXPECT_LT(worst, 2e-7);
  EXPECT_EQ(t.decode(-1.0f), 0.0f);
  EXPECT_NEAR(t.decode(2.0f), 1.0f, 1e-7);
}
