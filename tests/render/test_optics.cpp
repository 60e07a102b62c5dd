// Interface optics against closed forms: Snell's law, the critical angle, Fresnel.
#include <cmath>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "raindrop/render/optics.h"

using namespace raindrop;

namespace {

// Unit direction hitting a surface with normal (0, 0, 1) at incidence angle theta (from below).
glm::dvec3 incident(double theta) { return {std::sin(theta), 0, -std::cos(theta)}; }
const glm::dvec3 kNormal{0, 0, 1};

}  // namespace

TEST(Optics, SnellsLawHoldsAcrossAngles) {
  for (double eta : {1.0 / kWaterIndex, kWaterIndex, 1.0 / 1.5}) {
    for (int i = 0; i <= 89; ++i) {
      const double theta = i * M_PI / 180;
      const double sin_t = eta * std::sin(theta);
      const auto t = refract(incident(theta), kNormal, eta);
      if (sin_t > 1) {
        EXPECT_FALSE(t) << "eta " << eta << " theta " << i;
        continue;
      }
      ASSERT_TRUE(t) << "eta " << eta << " theta " << i;
      EXPECT_NEAR(glm::length(*t), 1.0, 1e-12);
      EXPECT_NEAR(t->x, sin_t, 1e-12);  // tangential component scaled by eta
      EXPECT_LT(t->z, 0);               // continues through the surface
    }
  }
}

TEST(Optics, NormalIncidenceIsUndeviated) {
  const auto t = refract({0, 0, -1}, kNormal, 1 / kWaterIndex);
  ASSERT_TRUE(t);
  EXPECT_NEAR(t->x, 0, 1e-15);
  EXPECT_NEAR(t->z, -1, 1e-15);
}

TEST(Optics, TotalInternalReflectionStartsAtTheCriticalAngle) {
  const double critical = critical_angle(kWaterIndex);
  EXPECT_NEAR(critical, std::asin(1 / 1.333), 1e-15);
  EXPECT_NEAR(critical * 180 / M_PI, 48.6066, 1e-3);
  // Water to air (eta = n): refracts just below, reflects just above.
  EXPECT_TRUE(refract(incident(critical - 1e-9), kNormal, kWaterIndex));
  EXPECT_FALSE(refract(incident(critical + 1e-9), kNormal, kWaterIndex));
  // At it the ray leaves tangent to the surface, finite. asin(1/n) rounds to either side of
  // the true critical angle: step down by ulps to the largest angle that still refracts,
  // and check (from Snell's law, outside the function under test) that it is grazing.
  double at = critical;
  for (int i = 0; i < 16 && kWaterIndex * std::sin(at) > 1.0; ++i) at = std::nextafter(at, 0.0);
  const double sin_t = kWaterIndex * std::sin(at);
  ASSERT_LE(sin_t, 1.0);
  ASSERT_GT(sin_t, 1.0 - 1e-14) << "not a grazing ray";
  const auto grazing = refract(incident(at), kNormal, kWaterIndex);
  ASSERT_TRUE(grazing) << "a ray that refracts, just, was reported as totally reflected";
  EXPECT_TRUE(std::isfinite(grazing->x) && std::isfinite(grazing->y) && std::isfinite(grazing->z));
  EXPECT_NEAR(grazing->z, 0, 1e-6);
  EXPECT_NEAR(grazing->x, 1, 1e-12);
  EXPECT_NEAR(glm::length(*grazing), 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(fresnel_reflectance(std::cos(critical + 1e-9), kWaterIndex), 1.0);
}

TEST(Optics, FresnelMatchesClosedForms) {
  const double n = kWaterIndex;
  // Normal incidence: ((n1 - n2) / (n1 + n2))^2 from either side.
  const double r0 = std::pow((n - 1) / (n + 1), 2);
  EXPECT_NEAR(fresnel_reflectance(1.0, 1 / n), r0, 1e-12);
  EXPECT_NEAR(fresnel_reflectance(1.0, n), r0, 1e-12);
  // Brewster's angle: p-polarised reflectance vanishes, so R = Rs / 2.
  const double brewster = std::atan(n);
  const double cos_i = std::cos(brewster), cos_t = std::cos(M_PI / 2 - brewster);
  const double rs = std::pow((cos_i - n * cos_t) / (cos_i + n * cos_t), 2);
  EXPECT_NEAR(fresnel_reflectance(cos_i, 1 / n), rs / 2, 1e-12);
  // Grazing incidence reflects everything; reflectance grows monotonically with angle.
  EXPECT_NEAR(fresnel_reflectance(0.0, 1 / n), 1.0, 1e-12);
  double previous = 0;
  for (int i = 0; i <= 90; ++i) {
    const double r = fresnel_reflectance(std::cos(i * M_PI / 180), 1 / n);
    EXPECT_GE(r, previous - 1e-15);
    EXPECT_LE(r, 1.0);
    previous = r;
  }
}

TEST(Optics, ReflectionMirrorsTheNormalComponent) {
  const glm::dvec3 d = glm::normalize(glm::dvec3(0.3, 0.4, -0.8));
  const glm::dvec3 r = reflect(d, kNormal);
  EXPECT_DOUBLE_EQ(r.x, d.x);
  EXPECT_DOUBLE_EQ(r.y, d.y);
  EXPECT_DOUBLE_EQ(r.z, -d.z);
}

TEST(Optics, WaterDispersionFitsTabulatedIndices) {
  EXPECT_NEAR(water_index(0.6563), 1.3312, 2e-4);  // C line
  EXPECT_NEAR(water_index(0.5893), 1.3330, 2e-4);  // D line
  EXPECT_NEAR(water_index(0.4861), 1.3371, 2e-4);  // F line
  EXPECT_GT(water_index(0.46), water_index(0.62));  // normal dispersion: blue bends more
}

TEST(Optics, InputsOutsideTheDomainStayFinite) {
  // Numerically past tangent (cos slightly negative / above one): clamped, never NaN.
  for (double cos_i : {-1e-12, 0.0, 1.0, 1.0 + 1e-12}) {
    const double r = fresnel_reflectance(cos_i, 1 / kWaterIndex);
    EXPECT_TRUE(std::isfinite(r));
  }
  const auto t = refract(glm::normalize(glm::dvec3(1, 0, 1e-17)), kNormal, 1 / kWaterIndex);
  ASSERT_TRUE(t);
  EXPECT_TRUE(std::isfinite(t->x) && std::isfinite(t->z));
}
